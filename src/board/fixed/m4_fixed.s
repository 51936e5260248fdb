@ The fixed-point cascade (`unlag::board::fixed::FixedCascade::process`) for Thumb-2 cores with the
@ 32x32->64 multiplies (SMULL/SMLAL) and SSAT: Cortex-M3/M4/M7/M33 and up. Hand-written; the
@ same integer arithmetic as the portable Rust code, so the same bits.
@
@ i32 unlag_m4_fixed_process(const FixedSection *sec /*r0*/, FixedState *state /*r1*/,
@                            i32 v /*r2*/, usize n /*r3*/)
@ returns the output; when a state or an output saturated it sets the state's overflow flag
@ (FixedState, #[repr(C)]: the n [x1, x2] pairs, then the flag byte, at offset 8 n) to 1.
@ FixedSection (#[repr(C)], 40 bytes): a11 a12 a21 a22 @0, b1 b2 @16, c1 c2 @24, d @32,
@ shift (u8, 1..=62) @36.
@
@ Per section: x1' = Qt(a11 x1 + a12 x2 + b1 v), x2' = Qt(a21 x1 + a22 x2 + b2 v),
@ v' = Qr(c1 x1 + c2 x2 + d v), accumulated exactly in 64 bits; Qt = >> 30 rounded towards
@ zero, Qr = >> shift rounded half up, both saturated to i32. Saturation is rare, so its
@ fix-up sits out of line behind a branch that is not taken.
    .syntax unified
    .thumb

    .pushsection .text.unlag_m4_fixed_process,"ax",%progbits
    .p2align 2
    .global unlag_m4_fixed_process
    .type unlag_m4_fixed_process,%function
    .thumb_func
unlag_m4_fixed_process:
    push {r4-r11, lr}
    cmp r3, #0
    beq .Lfx_done
.Lfx_section:
    ldrd r4, r5, [r1]            @ x1, x2
    @ x1' = Qt(a11 x1 + a12 x2 + b1 v) -> r10
    ldrd r9, r12, [r0]
    smull r6, r7, r9, r4
    smlal r6, r7, r12, r5
    ldr r9, [r0, #16]
    smlal r6, r7, r9, r2
    asr r8, r7, #31
    adds r6, r6, r8, lsr #2      @ + (2^30 - 1) when negative: rounds towards zero
    adc r7, r7, #0
    lsr r6, r6, #30
    orr r10, r6, r7, lsl #2
    ssat r8, #30, r7             @ fits in i32 iff the high word fits in 30 bits
    cmp r8, r7
    bne .Lfx_sat1
.Lfx_back1:
    @ x2' = Qt(a21 x1 + a22 x2 + b2 v) -> r12
    ldrd r9, r12, [r0, #8]
    smull r6, r7, r9, r4
    smlal r6, r7, r12, r5
    ldr r9, [r0, #20]
    smlal r6, r7, r9, r2
    asr r8, r7, #31
    adds r6, r6, r8, lsr #2
    adc r7, r7, #0
    lsr r6, r6, #30
    orr r12, r6, r7, lsl #2
    ssat r8, #30, r7
    cmp r8, r7
    bne .Lfx_sat2
.Lfx_back2:
    strd r10, r12, [r1], #8
    @ v' = Qr(c1 x1 + c2 x2 + d v) -> r2
    ldrd r9, r10, [r0, #24]
    smull r6, r7, r9, r4
    smlal r6, r7, r10, r5
    ldr r9, [r0, #32]
    smlal r6, r7, r9, r2
    ldrb r9, [r0, #36]
    adds r0, r0, #40
    subs r9, r9, #1              @ k = shift - 1, 0..=61
    cmp r9, #32
    bhs .Lfx_big
    lsr r6, r6, r9               @ (hi:lo) >> k, k < 32
    rsb r8, r9, #32
    lsl r8, r7, r8
    orr r6, r6, r8
    asr r7, r7, r9
.Lfx_round:
    adds r6, r6, #1              @ ((acc >> k) + 1) >> 1
    adc r7, r7, #0
    asrs r7, r7, #1
    rrx r2, r6
    cmp r7, r2, asr #31          @ fits in i32 iff the high word is the low word's sign
    bne .Lfx_sat3
.Lfx_back3:
    subs r3, r3, #1
    bne .Lfx_section
.Lfx_done:
    mov r0, r2
    pop {r4-r11, pc}
.Lfx_big:                        @ k >= 32: (hi:lo) >> k = hi >> (k - 32)
    sub r8, r9, #32
    asr r6, r7, r8
    asr r7, r7, #31
    b .Lfx_round
.Lfx_sat1:
    mvn r10, #0x80000000
    eor r10, r10, r7, asr #31    @ i32::MIN or i32::MAX, by the sign
    add r8, r1, r3, lsl #3       @ the flag: after the r3 sections left, this one included
    movs r9, #1
    strb r9, [r8]
    b .Lfx_back1
.Lfx_sat2:
    mvn r12, #0x80000000
    eor r12, r12, r7, asr #31
    add r8, r1, r3, lsl #3
    movs r9, #1
    strb r9, [r8]
    b .Lfx_back2
.Lfx_sat3:
    mvn r2, #0x80000000
    eor r2, r2, r7, asr #31
    add r8, r1, r3, lsl #3       @ r1 has moved on by one section already
    movs r9, #1
    strb r9, [r8, #-8]
    b .Lfx_back3
    .p2align 2                   @ NOP padding inside the symbol (see bench/gen_m4_kernels.py)
    .size unlag_m4_fixed_process, .-unlag_m4_fixed_process
    .popsection
