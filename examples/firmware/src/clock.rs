//! Time in QEMU's instruction count: SysTick runs on the core clock (25 MHz on mps2-an386),
//! and under `-icount shift=0` QEMU's virtual clock advances one nanosecond an instruction,
//! so a tick is 40 instructions. This is QEMU's count of instructions, not a real Cortex-M4's
//! cycles (which add wait states, multi-cycle loads and floating point).

use core::sync::atomic::{AtomicU32, Ordering};
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
#[cfg(not(feature = "profile"))]
use cortex_m_rt::exception;

/// SysTick's reload: the whole 24-bit range, so that the interrupt comes rarely (or, with
/// the feature `profile`, often: [`crate::profile::PERIOD_TICKS`]).
#[cfg(not(feature = "profile"))]
const RELOAD: u32 = 0x00FF_FFFF;
#[cfg(feature = "profile")]
const RELOAD: u32 = crate::profile::PERIOD_TICKS;
/// Instructions a SysTick tick stands for under `-icount shift=0` (1 ns each at 25 MHz).
pub const INSTRUCTIONS_PER_TICK: u64 = 40;

/// Turns of the 24-bit counter so far.
static WRAPS: AtomicU32 = AtomicU32::new(0);

#[cfg(not(feature = "profile"))]
#[exception]
fn SysTick() {
    wrapped();
}

/// Counts one turn of the counter (SysTick's handler).
pub fn wrapped() {
    WRAPS.fetch_add(1, Ordering::Relaxed);
}

/// Starts SysTick counting down from its full range, interrupting at each turn.
pub fn start(syst: &mut SYST) {
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(RELOAD);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}

/// Ticks since [`start`].
pub fn ticks() -> u64 {
    loop {
        let before = WRAPS.load(Ordering::Relaxed);
        let current = SYST::get_current();
        if WRAPS.load(Ordering::Relaxed) == before {
            return u64::from(before) * (u64::from(RELOAD) + 1) + u64::from(RELOAD - current);
        }
    }
}
