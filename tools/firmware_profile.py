#!/usr/bin/env python3
"""Where the firmware's instructions go, and what they would cost a real Cortex-M4.

    tools/firmware_profile.py [--f64] [--log FILE]

Builds and runs examples/firmware with the feature `profile` (and `f64` with --f64) under
QEMU, or reads the output of such a run from FILE. The firmware samples the program counter
and the return addresses above it every 40 960 instructions (163 840 in the f64 build) during
the real scans 2 to 9 (SysTick under `-icount`, so samples fall on instructions in proportion
to how often they run). Prints:

- the samples by function: the innermost function of this repository's core each sampled
  instruction was inlined into (addr2line), else its symbol (the soft-float routines, libm);
- the samples in double-precision software routines by the core function that called them;
- the instruction mix, by the classes of the Cortex-M4 Technical Reference Manual's timing
  tables, and the cycles each class costs there (zero wait states);
- the estimate: cycles per instruction, and cycles and milliseconds per scan at 168 MHz for
  the median instruction count the firmware printed.

The cycle figures are the TRM's (Arm DDI 0439B, "Processor instruction timings" and "FPU
instruction set", r0p1), with these choices where a count depends on what QEMU does not show:
a branch costs 1 + P with P = 2 when taken and conditional branches are taken half the time;
a load costs 2 (1 when it follows another load, which is ignored here), a store 1 (the TRM's
STR pairing rule); a divide 7 (2 to 12). Wait states of flash, bus contention and the FPU's
pipelining of VMLA are not modelled: see docs/journal.md for what a board must confirm.
"""
import bisect
import collections
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FIRMWARE = os.path.join(ROOT, "examples", "firmware")
ELF = os.path.join(FIRMWARE, "target", "thumbv7em-none-eabihf", "release", "slamesh-firmware")
CLOCK_MHZ = 168

# (class, cycles) by mnemonic prefix, longest prefix first; `N` is added for register lists.
CLASSES = [
    ("vdiv", "FP divide, square root", 14), ("vsqrt", "FP divide, square root", 14),
    ("vmla", "FP multiply-accumulate", 3), ("vmls", "FP multiply-accumulate", 3),
    ("vnmla", "FP multiply-accumulate", 3), ("vnmls", "FP multiply-accumulate", 3),
    ("vfma", "FP multiply-accumulate", 3), ("vfms", "FP multiply-accumulate", 3),
    ("vfnma", "FP multiply-accumulate", 3), ("vfnms", "FP multiply-accumulate", 3),
    ("vldr", "FP load, store", 2), ("vstr", "FP load, store", 2),
    ("vldm", "FP load, store multiple", 1), ("vstm", "FP load, store multiple", 1),
    ("vpush", "FP load, store multiple", 1), ("vpop", "FP load, store multiple", 1),
    ("v", "FP arithmetic, compare, convert, move", 1),
    ("ldrd", "load, store", 3), ("strd", "load, store", 3),
    ("ldm", "load, store multiple", 1), ("stm", "load, store multiple", 1),
    ("push", "load, store multiple", 1), ("pop", "load, store multiple", 1),
    ("ldr", "load, store", 2), ("str", "store", 1),
    ("sdiv", "integer divide", 7), ("udiv", "integer divide", 7),
    ("tbb", "table branch", 6), ("tbh", "table branch", 6),
    ("cbz", "branch", 2), ("cbnz", "branch", 2),
    ("bl", "branch", 3), ("bx", "branch", 3),
]
CONDITIONS = ("eq", "ne", "cs", "hs", "cc", "lo", "mi", "pl", "vs", "vc", "hi", "ls", "ge",
              "lt", "gt", "le")


def classify(mnemonic, operands):
    """The TRM class of one instruction and its cycles."""
    m = mnemonic.lower().split(".")[0]
    if m in ("b", "b.w", "b.n") or (m.startswith("b") and m[1:3] in CONDITIONS and len(m) <= 5):
        return ("branch", 3) if m == "b" else ("branch", 2)
    for prefix, name, cycles in CLASSES:
        if m.startswith(prefix):
            if name.endswith("multiple"):
                regs = len(re.findall(r"[rsd]\d+|lr|pc|sp", operands.split("{", 1)[-1]))
                span = re.search(r"\{(\w+)-(\w+)\}", operands)
                if span:
                    regs = int(span[2][1:]) - int(span[1][1:]) + 1
                return name, cycles + regs + (2 if "pc" in operands else 0)
            return name, cycles
    if m.startswith(("mul", "mla", "mls", "umull", "smull", "umlal", "smlal")):
        return "multiply", 1
    return "integer arithmetic, logic, move", 1


def disassemble(elf):
    out = subprocess.run(["llvm-objdump", "-d", "--no-show-raw-insn", elf],
                         capture_output=True, text=True, check=True).stdout
    code = {}
    for line in out.splitlines():
        m = re.match(r"\s+([0-9a-f]+):\s+(\S+)\s*(.*)", line)
        if m:
            code[int(m[1], 16)] = (m[2], m[3])
    return code


def symbols(elf):
    out = subprocess.run(["llvm-nm", "-n", "-C", elf], capture_output=True, text=True,
                         check=True).stdout
    syms = []
    for line in out.splitlines():
        p = line.split(None, 2)
        if len(p) == 3 and p[1] in "tTwW":
            syms.append((int(p[0], 16) & ~1, p[2]))
    return syms


def short(symbol):
    """A symbol's last name, with the module of a trait impl (`quaternion_ops::mul`)."""
    symbol = re.sub(r"::h[0-9a-f]{16}$", "", symbol)
    last = symbol.split("::")[-1]
    if "::_$LT$impl" in symbol:
        return symbol.split("::_$LT$impl")[0].split("::")[-1] + "::" + last
    return last


def owners(elf, pcs, syms):
    """Per distinct pc, the innermost core function it was inlined into, else its symbol."""
    addrs = [a for a, _ in syms]
    distinct = sorted(set(pcs))
    out = subprocess.run(["addr2line", "-e", elf, "-f", "-i", "-C", "-a"] + [hex(p) for p in distinct],
                         capture_output=True, text=True, check=True).stdout.splitlines()
    owner, current, frames = {}, None, []

    def close():
        if current is None:
            return
        name = None
        for fn, place in frames:
            if "/core/src/" in place and "/library/core/" not in place and "rustc" not in place:
                name = fn.split("::")[-2] + "::" + fn.split("::")[-1] if "::" in fn else fn
                name = re.sub(r"::h[0-9a-f]{16}$", "", name)
                break
        if name is None:
            i = bisect.bisect_right(addrs, current) - 1
            name = "[" + short(syms[i][1] if i >= 0 else "?") + "]"
        owner[current] = name

    i = 0
    while i < len(out):
        line = out[i]
        if line.startswith("0x"):
            close()
            current, frames = int(line, 16), []
            i += 1
            continue
        frames.append((line, out[i + 1] if i + 1 < len(out) else ""))
        i += 2
    close()
    return owner


def is_soft(name):
    """A double-precision software routine (compiler-builtins' or its AEABI entry points)."""
    return bool(re.search(r"\[(__aeabi_[dlui]*[d2]|__aeabi_d|__\w+df\d|__\w+di\d)", name))


def is_builtin(name):
    """A routine of the compiler's or libm's, not the project's."""
    return name.startswith("[") and (name.startswith("[__") or name[1:].split("]")[0] in (
        "memmove", "memcpy", "memset", "fmax", "fmin", "fmaxf", "fminf"))


def main():
    args = sys.argv[1:]
    features = "profile,f64" if "--f64" in args else "profile"
    if "--log" in args:
        text = open(args[args.index("--log") + 1]).read()
    else:
        env = dict(os.environ, SLAMESH_DATA=os.environ.get("SLAMESH_DATA", "../shared/data"))
        text = subprocess.run(["cargo", "run", "--release", "--features", features],
                              cwd=FIRMWARE, env=env, capture_output=True, text=True).stdout
    start = text.find("pc-samples")
    period = re.search(r"pc-samples \d+ every (\d+) instructions", text)
    if start < 0:
        sys.exit("no pc-samples in the firmware's output (built without SLAMESH_DATA?)")
    samples = []
    for line in text[start:].splitlines()[1:]:
        words = line.split()
        if words and all(re.fullmatch(r"[0-9a-f]{8}", w) for w in words):
            # The pc, then each return address moved back onto its call instruction.
            pc, *ret = [int(w, 16) & ~1 for w in words]
            samples.append([pc] + [r - 2 if r else 0 for r in ret])
    pcs = [s[0] for s in samples]
    median = re.search(r"median (\d+) instructions a scan", text)
    n = len(pcs)
    code, syms = disassemble(ELF), symbols(ELF)
    owner = owners(ELF, sorted({w for s in samples for w in s if w}), syms)

    print(f"{n} samples ({features}), one every {int(period[1]) if period else '?'} instructions "
          "of real scans 2 to 9\n")
    print("by function (core functions with what was inlined into them; [symbol] otherwise):")
    by = collections.Counter(owner.get(p, "?") for p in pcs)
    for name, c in by.most_common(25):
        print(f"  {100 * c / n:5.1f} %  {name}")
    soft = sum(c for name, c in by.items() if is_soft(name))
    print(f"  ({100 * soft / n:.1f} % in double-precision software routines)\n")
    print("the double-precision software routines by the core function that called them")
    print("(through nalgebra or libm when one of them is between; else the first other caller):")
    callers = collections.Counter()
    for s in samples:
        if is_soft(owner.get(s[0], "?")):
            # The first caller in the core, else the first that is not a compiler routine.
            names = [owner.get(w, "?") for w in s[1:] if w]
            caller = next((c for c in names if not c.startswith("[")),
                          next((c for c in names if not is_builtin(c)), "?"))
            callers[caller] += 1
    for name, c in callers.most_common(15):
        print(f"  {100 * c / n:5.1f} %  {name}")
    print()

    mix, cycles = collections.Counter(), collections.Counter()
    for p in pcs:
        mnemonic, operands = code.get(p, ("?", ""))
        name, c = classify(mnemonic, operands)
        mix[name] += 1
        cycles[name] += c
    total = sum(cycles.values())
    print(f"{'instruction class':<40} {'instructions':>12} {'cycles each':>11} {'cycles':>8}")
    for name, c in mix.most_common():
        print(f"  {name:<38} {100 * c / n:>10.1f} % {cycles[name] / c:>11.2f} "
              f"{100 * cycles[name] / total:>6.1f} %")
    cpi = total / n
    print(f"\ncycles per instruction (zero wait states): {cpi:.2f}")
    if median:
        instructions = int(median[1])
        print(f"median scan: {instructions:,} instructions -> {instructions * cpi / 1e6:,.0f} M cycles, "
              f"{instructions * cpi / (CLOCK_MHZ * 1e3):,.0f} ms at {CLOCK_MHZ} MHz")


if __name__ == "__main__":
    main()
