#!/usr/bin/env python3
"""Writes src/board/fixed/direct/m4_direct.s: the Thumb-2 kernels of the direct-form fixed-point
cascade (`unlag::board::fixed::direct::DirectCascade::process` and `process_in_place`) for 1..=4
sections.

    python3 bench/gen_m4_direct.py      # rewrites the file; commit the result
    python3 bench/gen_m4_direct.py OUT.s  # writes OUT.s instead (.ci/run diffs it against the file)

Layouts (see src/board/fixed/direct.rs, both #[repr(C)]): coefficients = per section
[b0, b1, b2, na1, na2] (i32, Q2.30, na = -a); state = [x1, x2], then per section [y1, y2, e],
then the overflow flag (a byte). Arithmetic, per section, exactly as the portable code:

    acc = e + b0 x0 + b1 x1 + b2 x2 + na1 y1 + na2 y2     (SMLAL into the pair e:hi, hi = 0)
    hi  = SSAT(hi, 30)                                     (sets the sticky Q flag if clamped)
    y   = (hi << 2) | (e >> 30);  e = e & (2^30 - 1)       (LSR + ORR, BFC)

The Q flag is cleared on entry and read on exit: set, it sets the state's overflow flag.
LDM/STM need ascending registers, so the state words are loaded and stored in their memory
order: a section's new [y1, y2, e] is stored from registers (y, old y1, e) in ascending order,
which the register choice below guarantees.
"""
import os
import sys

MAX_N = 4
out = []
emit = out.append


def func_head(name):
    emit(f"    .pushsection .text.{name},\"ax\",%progbits")
    emit("    .p2align 2")
    emit(f"    .global {name}")
    emit(f"    .type {name},%function")
    emit("    .thumb_func")
    emit(f"{name}:")


def func_tail(name):
    # Pad with a NOP inside the symbol, so that the linker's fill after it is not
    # disassembled as a stray branch of this function (.ci/no-panic.sh reads the disassembly).
    emit("    .p2align 2")
    emit(f"    .size {name}, .-{name}")
    emit("    .popsection")
    emit("")


def r(i):
    return "lr" if i == 14 else f"r{i}"


def regs(lst):
    assert lst == sorted(lst) and len(set(lst)) == len(lst), lst
    return "{" + ", ".join(r(i) for i in lst) + "}"


HI = 14


def quantise(y, e):
    emit(f"    ssat lr, #30, lr")
    emit(f"    lsr {r(y)}, {r(e)}, #30")
    emit(f"    orr {r(y)}, {r(y)}, lr, lsl #2")
    emit(f"    bfc {r(e)}, #30, #2")


def smlal(e, c, v):
    emit(f"    smlal {r(e)}, lr, {r(c)}, {r(v)}")


def call_kernel(n):
    """i32 unlag_m4_direct_call_N(const DirectSection *c /*r0*/, DirectState *s /*r1*/,
    i32 x /*r2*/): one sample. Coefficients of a section in one LDM, its state in one more
    (the first section's with the input history), one STM back."""
    name = f"unlag_m4_direct_call_{n}"
    emit(f"@ One sample through {n} section(s): x in r2, y out in r0.")
    func_head(name)
    emit("    push {r4-r11, lr}")
    emit("    mov lr, #0")
    emit("    msr APSR_nzcvq, lr          @ clears Q (and the flags)")
    pool = list(range(2, 13))
    # Section 1: x0 = r2; state x1, x2, y1, y2, e; coefficients r5-r9.
    x0, x1, x2 = 2, 3, 4
    c = [5, 6, 7, 8, 9]
    y1, y2, e = 10, 11, 12
    emit(f"    ldm r1, {regs([x1, x2, y1, y2, e])}")
    emit(f"    ldm r0!, {regs(c)}")
    for ci, v in zip(c, [x0, x1, x2, y1, y2]):
        smlal(e, ci, v)
    y = c[0]
    quantise(y, e)
    emit(f"    stmia r1!, {regs([x0, x1, y, y1, e])}")
    v = (y, y1, y2)
    for k in range(1, n):
        free = [i for i in pool if i not in v]
        c, (y1, y2, e) = free[:5], free[5:8]
        emit(f"    ldm r1, {regs([y1, y2, e])}")
        emit(f"    ldm r0!, {regs(c)}")
        emit("    mov lr, #0")
        for ci, vi in zip(c, [v[0], v[1], v[2], y1, y2]):
            smlal(e, ci, vi)
        y = c[0]
        quantise(y, e)
        emit(f"    stmia r1!, {regs([y, y1, e])}")
        v = (y, y1, y2)
    # r1 now points at the overflow flag.
    t = [i for i in range(2, 13) if i != v[0]][0]
    emit(f"    mrs {r(t)}, APSR")
    emit(f"    lsls {r(t)}, {r(t)}, #5          @ Q -> C")
    emit(f"    bcs .L{name}_sat")
    emit(f".L{name}_back:")
    emit(f"    mov r0, {r(v[0])}")
    emit("    pop {r4-r11, pc}")
    emit(f".L{name}_sat:")
    emit(f"    movs {r(t)}, #1")
    emit(f"    strb {r(t)}, [r1]")
    emit(f"    b .L{name}_back")
    func_tail(name)


def block_kernel(n):
    """void unlag_m4_direct_block_N(const DirectSection *c /*r0*/, DirectState *s /*r1*/,
    i32 *buf /*r2*/, usize len /*r3*/), in place. Registers: r0 walks the coefficients and is
    reset every sample, r2 the buffer, r3 counts down; a section's coefficients come in two
    LDMs (b, then -a, into registers the first part freed), so that ten registers suffice for a
    section. The state: with one or two sections r1 stays put (at the second section's state,
    which LDM/STM reach, the first's just below it by LDMDB/STMDB), with more it walks and is
    reset every sample."""
    fixed_state = n <= 2
    name = f"unlag_m4_direct_block_{n}"
    emit(f"@ A block in place through {n} section(s).")
    func_head(name)
    emit("    push {r4-r11, lr}")
    emit("    mov lr, #0")
    emit("    msr APSR_nzcvq, lr          @ clears Q (and the flags)")
    if n == 2:
        emit("    add r1, r1, #20              @ the second section's state")
    emit("    cmp r3, #0")
    emit(f"    beq .L{name}_done")
    emit(f".L{name}_loop:")
    pool = list(range(4, 13))
    x0, x1, x2 = 4, 5, 6
    b = [7, 8, 9]
    y1, y2, e = 10, 11, 12
    emit(f"    ldr {r(x0)}, [r2]")
    first_ld = "ldmdb r1" if n == 2 else "ldm r1"
    emit(f"    {first_ld}, {regs([x1, x2, y1, y2, e])}")
    emit(f"    ldm r0!, {regs(b)}")
    emit("    mov lr, #0")
    for ci, vi in zip(b, [x0, x1, x2]):
        smlal(e, ci, vi)
    a = [x2, b[0]]
    emit(f"    ldm r0!, {regs(a)}")
    smlal(e, a[0], y1)
    smlal(e, a[1], y2)
    y = b[1]
    assert x1 < y < y1
    quantise(y, e)
    first_st = {1: "stm r1", 2: "stmdb r1"}.get(n, "stmia r1!")
    emit(f"    {first_st}, {regs([x0, x1, y, y1, e])}")
    v = (y, y1, y2)
    for k in range(1, n):
        free = [i for i in pool if i not in v]
        b, (y1, y2, e) = free[:3], free[3:6]
        emit(f"    ldm r1, {regs([y1, y2, e])}")
        emit(f"    ldm r0!, {regs(b)}")
        emit("    mov lr, #0")
        for ci, vi in zip(b, v):
            smlal(e, ci, vi)
        dead = sorted(list(v) + b)
        a = dead[:2]
        emit(f"    ldm r0!, {regs(a)}")
        smlal(e, a[0], y1)
        smlal(e, a[1], y2)
        y = dead[0]
        assert y < y1
        quantise(y, e)
        emit(f"    {'stm r1' if fixed_state else 'stmia r1!'}, {regs([y, y1, e])}")
        v = (y, y1, y2)
    emit(f"    str {r(v[0])}, [r2], #4")
    emit(f"    sub r0, r0, #{20 * n}")
    if not fixed_state:
        emit(f"    sub r1, r1, #{8 + 12 * n}")
    emit("    subs r3, r3, #1")
    emit(f"    bne .L{name}_loop")
    emit(f".L{name}_done:")
    emit("    mrs r4, APSR")
    emit("    lsls r4, r4, #5             @ Q -> C")
    emit(f"    bcs .L{name}_sat")
    emit("    pop {r4-r11, pc}")
    emit(f".L{name}_sat:")
    emit("    movs r4, #1")
    flag = 8 + 12 * n - (20 if n == 2 else 0)
    emit(f"    strb r4, [r1, #{flag}]")
    emit("    pop {r4-r11, pc}")
    func_tail(name)


emit("@ Generated by bench/gen_m4_direct.py. Do not edit: change the generator and rerun it.")
emit("@ Thumb-2 with SMLAL, SSAT and the sticky Q flag: Cortex-M3, M4, M7, M33 and later.")
emit("@ r4-r11 are saved; no stack frame otherwise.")
emit("    .syntax unified")
emit("    .thumb")
emit("")
for n in range(1, MAX_N + 1):
    call_kernel(n)
    block_kernel(n)
# The committed file, or the path given (CI regenerates into a temporary file and diffs).
path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
    os.path.dirname(os.path.abspath(__file__)), "..", "src", "board", "fixed", "direct", "m4_direct.s"
)
with open(path, "w") as f:
    f.write("\n".join(out).rstrip("\n") + "\n")
print(f"wrote {os.path.normpath(path)}")
