#!/usr/bin/env python3
"""Writes src/board/compensator/m4_kernels.s: the hand-scheduled Thumb-2/VFP kernels of the f32
cascade (`CascadeCoefficients::process` and `process_in_place`) for 1..=4 sections.

    python3 bench/gen_m4_kernels.py      # rewrites the file; commit the result
    python3 bench/gen_m4_kernels.py OUT.s  # writes OUT.s instead (.ci/run diffs it against the file)

Layouts (see src/board/compensator.rs): coefficients `#[repr(C)]` = per section [b0, b1, a1, a2],
then b2 of every section (5N floats); state `#[repr(C)]` = s2 of every section, then s1 of
every section (2N floats). Arithmetic: VMLA/VMLS (multiply, round, then add/subtract, round:
not fused), in the order of the portable code, so the results are bit-identical to it.
"""
import os
import sys

MAX_N = 4
out = []
emit = out.append


def s(i):
    return f"s{i}"


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


def emit_sections(n, reg, p, v):
    """Sample phase `p` of a block kernel through `n` sections, input in register `v`:
    section i's s1, s2 and scratch are reg(i, p), reg(i, p + 1), reg(i, p + 2); coefficients
    as the block kernels load them (b0, b1, a1, a2 of each section, then every b2). Returns
    the register holding the output."""
    for i in range(n):
        st1, st2, tmp = reg(i, p), reg(i, p + 1), reg(i, p + 2)
        b0, b1, a1, a2, b2 = s(4 * i), s(4 * i + 1), s(4 * i + 2), s(4 * i + 3), s(4 * n + i)
        emit(f"    vmla.f32 {st1}, {b0}, {v}")
        emit(f"    vmla.f32 {st2}, {b1}, {v}")
        emit(f"    vmls.f32 {st2}, {a1}, {st1}")
        emit(f"    vmul.f32 {tmp}, {b2}, {v}")
        emit(f"    vmls.f32 {tmp}, {a2}, {st1}")
        v = st1
    return v


def emit_load(n, reg):
    """Loads the coefficients into s0.. and the state as phase 0: s1 of section i into
    reg(i, 0), s2 into reg(i, 1)."""
    emit(f"    vldm r0, {{s0-s{5 * n - 1}}}")
    for i in range(n):
        emit(f"    vldr {reg(i, 0)}, [r1, #{4 * (n + i)}]")  # s1
        emit(f"    vldr {reg(i, 1)}, [r1, #{4 * i}]")  # s2


def emit_store(n, reg, p):
    """Writes back the state of phase `p`: s1 of each section after every s2."""
    for i in range(n):
        emit(f"    vstr {reg(i, p)}, [r1, #{4 * (n + i)}]")
        emit(f"    vstr {reg(i, p + 1)}, [r1, #{4 * i}]")


def call_kernel(n):
    """f32 unlag_m4_cascade_call_N(const f32 *coeffs /*r0*/, f32 *state /*r1*/, f32 x /*s0*/)."""
    name = f"unlag_m4_cascade_call_{n}"
    emit(f"@ One sample through {n} section(s): x in s0, y out in s0.")
    func_head(name)
    top = 7 * n  # highest register used
    if top >= 16:
        emit(f"    vpush {{s16-s{top}}}")
    b0 = lambda i: s(1 + 4 * i)
    b1 = lambda i: s(2 + 4 * i)
    a1 = lambda i: s(3 + 4 * i)
    a2 = lambda i: s(4 + 4 * i)
    b2 = lambda i: s(4 * n + 1 + i)
    st2 = lambda i: s(5 * n + 1 + i)
    st1 = lambda i: s(6 * n + 1 + i)
    emit(f"    vldm r0, {{s1-s{5 * n}}}")
    emit(f"    vldm r1, {{s{5 * n + 1}-s{7 * n}}}")
    v = "s0"
    for i in range(n):
        emit(f"    vmla.f32 {st1(i)}, {b0(i)}, {v}")     # y = s1 + b0 v
        emit(f"    vmla.f32 {st2(i)}, {b1(i)}, {v}")     # s2 + b1 v
        emit(f"    vmls.f32 {st2(i)}, {a1(i)}, {st1(i)}")  # new s1 = (s2 + b1 v) - a1 y
        emit(f"    vmul.f32 {b2(i)}, {b2(i)}, {v}")     # b2 v
        emit(f"    vmls.f32 {b2(i)}, {a2(i)}, {st1(i)}")  # new s2 = b2 v - a2 y
        v = st1(i)
    # New s2 of every section sit in the b2 registers, new s1 in the old s2 registers: one
    # consecutive run, in the state's memory order.
    emit(f"    vstm r1, {{s{4 * n + 1}-s{6 * n}}}")
    emit(f"    vmov.f32 s0, {v}")
    if top >= 16:
        emit(f"    vpop {{s16-s{top}}}")
    emit("    bx lr")
    func_tail(name)


def block_kernel(n):
    """void unlag_m4_cascade_block_N(const f32 *coeffs /*r0*/, f32 *state /*r1*/,
    f32 *buf /*r2*/, usize len /*r3*/), in place."""
    name = f"unlag_m4_cascade_block_{n}"
    emit(f"@ A block in place through {n} section(s), coefficients and state in registers.")
    emit("@ Each section's three registers rotate roles (s1, s2, scratch) every sample, so the")
    emit("@ loop body is three samples long and moves nothing.")
    func_head(name)
    top = 8 * n - 1
    if top >= 16:
        emit(f"    vpush {{s16-s{top}}}")
    reg = lambda i, k: s(5 * n + 3 * i + k % 3)
    emit_load(n, reg)
    # q = len / 3 (exact for every 32-bit len), r3 = len % 3.
    emit("    movw r12, #0xaaab")
    emit("    movt r12, #0xaaaa")
    emit("    umull r12, r0, r3, r12")
    emit("    lsrs r0, r0, #1")
    emit("    add r12, r0, r0, lsl #1")
    emit("    subs r3, r3, r12")
    emit("    cmp r0, #0")
    emit(f"    beq .L{name}_rem")

    def sample(p):
        emit(f"    vldr {reg(0, p + 2)}, [r2]")
        emit(f"    vstmia r2!, {{{emit_sections(n, reg, p, reg(0, p + 2))}}}")

    store = lambda p: emit_store(n, reg, p)

    emit(f".L{name}_loop:")
    for p in range(3):
        sample(p)
    emit("    subs r0, r0, #1")
    emit(f"    bne .L{name}_loop")
    emit(f".L{name}_rem:")
    emit("    cmp r3, #0")
    emit(f"    beq .L{name}_store0")
    sample(0)
    emit("    cmp r3, #1")
    emit(f"    beq .L{name}_store1")
    sample(1)
    store(2)
    emit(f"    b .L{name}_done")
    emit(f".L{name}_store1:")
    store(1)
    emit(f"    b .L{name}_done")
    emit(f".L{name}_store0:")
    store(0)
    emit(f".L{name}_done:")
    if top >= 16:
        emit(f"    vpop {{s16-s{top}}}")
    emit("    bx lr")
    func_tail(name)


# Samples per pass of the wide block kernel.
WIDE = 6


def wide_block_kernel(n):
    """void unlag_m4_cascade_block_N(const f32 *coeffs /*r0*/, f32 *state /*r1*/,
    f32 *buf /*r2*/, usize len /*r3*/), in place, for few sections (n <= 2): the block is read
    WIDE samples at a time by one VLDM and written back by two VSTMs, so that the loads, stores
    and loop count cost under one instruction a sample."""
    name = f"unlag_m4_cascade_block_{n}"
    emit(f"@ A block in place through {n} section(s), {WIDE} samples a pass: one VLDM of the")
    emit("@ inputs, two VSTMs of the outputs. Sections before the last rotate three registers")
    emit(f"@ (s1, s2, scratch) every sample; the last rotates {WIDE}, so that its outputs y_p stay")
    emit(f"@ in consecutive registers until they are stored. Same arithmetic as the call kernel.")
    func_head(name)
    base = 5 * n
    last = n - 1

    def reg(i, k):
        if i == last:
            return s(base + 3 * last + k % WIDE)
        return s(base + 3 * i + k % 3)

    xbase = base + 3 * last + WIDE
    x = lambda p: s(xbase + p)
    top = xbase + WIDE - 1
    assert top <= 31
    if top >= 16:
        emit(f"    vpush {{s16-s{top}}}")
    emit_load(n, reg)
    # q = len / 6 (exact for every 32-bit len), r3 = len % 6.
    emit("    movw r12, #0xaaab")
    emit("    movt r12, #0xaaaa")
    emit("    umull r12, r0, r3, r12")
    emit("    lsrs r0, r0, #2")
    emit("    add r12, r0, r0, lsl #1")
    emit("    sub r3, r3, r12, lsl #1")
    emit("    cmp r0, #0")
    emit(f"    beq .L{name}_rem")

    sample = lambda p, v: emit_sections(n, reg, p, v)
    store = lambda p: emit_store(n, reg, p)

    # y_p sits in the last section's register p until sample p + WIDE - 2 takes it as scratch:
    # the first WIDE - 2 outputs are stored before that sample, the last two after the pass.
    early = WIDE - 2
    emit(f".L{name}_loop:")
    emit(f"    vldm r2, {{{x(0)}-{x(WIDE - 1)}}}")
    for p in range(WIDE):
        if p == early:
            emit(f"    vstmia r2!, {{{reg(last, 0)}-{reg(last, early - 1)}}}")
        sample(p, x(p))
    emit(f"    vstmia r2!, {{{reg(last, early)}-{reg(last, WIDE - 1)}}}")
    emit("    subs r0, r0, #1")
    emit(f"    bne .L{name}_loop")
    # The rest, one sample at a time, the rings going on from phase 0.
    emit(f".L{name}_rem:")
    for p in range(WIDE - 1):
        emit(f"    cmp r3, #{p}")
        emit(f"    beq .L{name}_store{p}")
        emit(f"    vldr {x(0)}, [r2]")
        y = sample(p, x(0))
        emit(f"    vstmia r2!, {{{y}}}")
    store(WIDE - 1)
    emit(f"    b .L{name}_done")
    for p in range(WIDE - 1):
        emit(f".L{name}_store{p}:")
        store(p)
        if p != WIDE - 2:
            emit(f"    b .L{name}_done")
    emit(f".L{name}_done:")
    if top >= 16:
        emit(f"    vpop {{s16-s{top}}}")
    emit("    bx lr")
    func_tail(name)


emit("@ Generated by bench/gen_m4_kernels.py. Do not edit: change the generator and rerun it.")
emit("@ Cortex-M4F (and any Thumb-2 core with a single-precision VFP and 32 S registers).")
emit("@ AAPCS-VFP: s16-s31 are callee-saved (pushed when used); no stack frame otherwise.")
emit("@ The module-level assembler does not see the target's FPU: name the one the code needs")
emit("@ (a subset of every single-precision FPU of Cortex-M4F, M7, M33 and later).")
emit("    .fpu fpv4-sp-d16")
emit("    .syntax unified")
emit("    .thumb")
emit("")
for n in range(1, MAX_N + 1):
    call_kernel(n)
    if n <= 2:
        wide_block_kernel(n)
    else:
        block_kernel(n)
# The committed file, or the path given (CI regenerates into a temporary file and diffs).
path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
    os.path.dirname(os.path.abspath(__file__)), "..", "src", "board", "compensator", "m4_kernels.s"
)
with open(path, "w") as f:
    f.write("\n".join(out).rstrip("\n") + "\n")
print(f"wrote {os.path.normpath(path)}")
