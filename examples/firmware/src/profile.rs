//! PC sampling (feature `profile`): SysTick interrupts every [`PERIOD_TICKS`] ticks, and while
//! [`sampling`] is on, its handler records the interrupted instruction's address from the
//! exception frame, and the first [`CALLERS`] return addresses it finds above it (the link
//! register, then the stack: words that point just after a `BL` or `BLX` instruction), so
//! that time in a shared routine (the `f64` software routines) can be charged to its callers.
//! Under `-icount` a tick is a fixed number of instructions, so the samples fall on
//! instructions in proportion to how often they run: the instruction mix, not QEMU's time.
//! `tools/firmware_profile.py` turns the printed samples into a profile and an estimate of a
//! real M4's cycles.

use core::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use cortex_m_semihosting::hprintln;

/// SysTick's reload while profiling: an interrupt every 1 024 ticks (40 960 instructions), or
/// every 4 096 in the `f64` build, whose scans take four times the instructions (so that the
/// samples of scans 2 to 9 fit [`CAPACITY`] in both).
#[cfg(not(feature = "f64"))]
pub const PERIOD_TICKS: u32 = 1_023;
#[cfg(feature = "f64")]
pub const PERIOD_TICKS: u32 = 4_095;
/// Return addresses kept per sample.
const CALLERS: usize = 3;
/// Words per sample: the pc and the callers (0 where none was found).
const WORDS: usize = 1 + CALLERS;
/// Samples kept at most (512 KB of RAM).
const CAPACITY: usize = 32_768;
/// Words of stack searched for return addresses.
const SEARCH: usize = 48;

static SAMPLING: AtomicBool = AtomicBool::new(false);
static COUNT: AtomicUsize = AtomicUsize::new(0);
/// The sampled addresses. Written by the handler only, read after sampling stops.
static mut SAMPLES: [[u32; WORDS]; CAPACITY] = [[0; WORDS]; CAPACITY];

/// Turns sampling on or off.
pub fn sampling(on: bool) {
    SAMPLING.store(on, Ordering::SeqCst);
}

// The SysTick vector: hands the exception frame (on the main stack: the firmware runs in
// thread mode on MSP) to `tick` before any prologue moves the stack pointer.
core::arch::global_asm!(
    ".section .text.SysTick",
    ".global SysTick",
    ".type SysTick, %function",
    ".thumb_func",
    "SysTick:",
    "    mrs r0, msp",
    "    mov r1, lr",
    "    b {tick}",
    tick = sym tick,
);

extern "C" {
    /// The start and end of the code (cortex-m-rt's linker script).
    static __stext: u32;
    static __etext: u32;
}

/// Whether `word` is a Thumb return address: odd, in the code, just after a 32-bit `BL` or a
/// 16-bit `BLX` register.
fn is_return(word: u32, text: (u32, u32)) -> bool {
    let at = word & !1;
    if word & 1 == 0 || at < text.0 + 4 || at > text.1 {
        return false;
    }
    // SAFETY: `at - 4 .. at` lies within the code, which is readable and never written.
    #[allow(unsafe_code)]
    let (h1, h2) = unsafe {
        (
            ((at - 4) as *const u16).read_volatile(),
            ((at - 2) as *const u16).read_volatile(),
        )
    };
    (h1 & 0xF800 == 0xF000 && h2 & 0xD000 == 0xD000) || h2 & 0xFF87 == 0x4780
}

/// Counts the turn for [`crate::clock`] and records the stacked pc (the frame's seventh
/// word) and the return addresses above it.
extern "C" fn tick(frame: *const u32, exc_return: u32) {
    crate::clock::wrapped();
    if !SAMPLING.load(Ordering::Relaxed) {
        return;
    }
    let n = COUNT.load(Ordering::Relaxed);
    if n >= CAPACITY {
        return;
    }
    // Only the linker symbols' addresses are taken.
    let text = (
        core::ptr::addr_of!(__stext) as u32,
        core::ptr::addr_of!(__etext) as u32,
    );
    // The frame: eight words, or 26 with the FP registers (EXC_RETURN bit 4 clear), plus one
    // of alignment when xPSR bit 9 says the stack was realigned.
    let mut sample = [0u32; WORDS];
    // SAFETY: `frame` is the main stack pointer at exception entry, where the hardware
    // stacked r0-r3, r12, lr, pc and xpsr, then the FP registers if bit 4 of EXC_RETURN is
    // clear; the interrupted code's stack follows, and RAM continues well past `SEARCH`
    // words above any stack pointer of this program (its stack starts at the end of RAM and
    // the words read past the end are the stack's own top, never beyond RAM: the search stops
    // at the first word that is not RAM). `SAMPLES` is written here only, one interrupt at a
    // time, and read by `print` after sampling stopped.
    #[allow(unsafe_code)]
    unsafe {
        let word = |i: usize| frame.add(i).read_volatile();
        sample[0] = word(6);
        let lr = word(5);
        let mut found = 0;
        if is_return(lr, text) {
            sample[1] = lr;
            found = 1;
        }
        let size = if exc_return & 0x10 == 0 { 26 } else { 8 } + ((word(7) >> 9) & 1) as usize;
        let ram_end = 0x2040_0000u32;
        for i in size..size + SEARCH {
            if found == CALLERS || frame.add(i) as u32 >= ram_end {
                break;
            }
            let w = word(i);
            if is_return(w, text) && w != sample[found.max(1) - 1] {
                sample[1 + found] = w;
                found += 1;
            }
        }
        core::ptr::addr_of_mut!(SAMPLES[n]).write_volatile(sample);
    }
    COUNT.store(n + 1, Ordering::Relaxed);
}

/// Prints the samples, one a line (the pc and its callers, hexadecimal) after
/// `pc-samples N`.
pub fn print() {
    sampling(false);
    let n = COUNT.load(Ordering::SeqCst);
    hprintln!(
        "pc-samples {} every {} instructions",
        n,
        (PERIOD_TICKS + 1) * 40
    );
    // SAFETY: sampling is off, so nothing writes `SAMPLES` any more: this is the only
    // reference to it from now on.
    #[allow(unsafe_code)]
    let samples: &[[u32; WORDS]; CAPACITY] = unsafe { &*core::ptr::addr_of!(SAMPLES) };
    for sample in &samples[..n.min(CAPACITY)] {
        let mut line: heapless::String<48> = heapless::String::new();
        for w in sample {
            let _ = core::fmt::write(&mut line, format_args!("{w:08x} "));
        }
        hprintln!("{}", line.as_str());
    }
}
