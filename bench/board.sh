#!/usr/bin/env bash
# Board budget: instructions per sample of the f32 and fixed-point compensators on a Cortex-M4F in QEMU
# (mps2-an386, -icount shift=0, SysTick at 40 instructions per tick), m = 2, 4, 8, one call
# per sample and block mode, with the idsp crate measured in the same run as the baseline.
#
#   bash bench/board.sh            # prints the Markdown table
#   bash bench/board.sh --update   # also replaces the "## Board (Cortex-M4, QEMU)" section
#                                  # of BENCHMARKS.md (and nothing else in it)
#
# Two builds of examples/bench_board.rs, both target-cpu=cortex-m4:
#   default: the flags in .cargo/config.toml (LLVM keeps VMUL and VADD apart on the M4);
#   vmla:    -C target-feature=-slowfpvmlx, which lets LLVM use VMLA/VMLS (chained
#            multiply-accumulate: the same rounding, so bit-identical results; fewer
#            instructions, but 3 cycles each on the M4 against 1 + 1 for VMUL + VADD).
#            Only the compiled code (idsp) changes: unlag's kernels are assembly.
# Needs: qemu-system-arm, rustup target thumbv7em-none-eabihf, python3.
set -euo pipefail
cd "$(dirname "$0")/.."
update=0
[ "${1:-}" = "--update" ] && update=1

root=${CARGO_TARGET_DIR:-target}
out_dir="$root/bench-board"
mkdir -p "$out_dir"
qemu=(qemu-system-arm -M mps2-an386 -nographic -monitor none -serial none
      -semihosting-config enable=on,target=native -icount shift=0 -kernel)
base_flags="-C link-arg=-Tlink.x -C target-cpu=cortex-m4"   # as in .cargo/config.toml

run_build() { # name, extra rustflags ("" = the flags of .cargo/config.toml, the usual target dir)
  local name=$1 extra=$2 dir="$root"
  if [ -n "$extra" ]; then
    dir="$root/bench-board-$name"
    RUSTFLAGS="$base_flags $extra" cargo build --quiet --release --no-default-features \
      --target thumbv7em-none-eabihf --example bench_board --target-dir "$dir" 2>"$out_dir/$name.build.txt" \
      || { cat "$out_dir/$name.build.txt" >&2; exit 1; }
  else
    cargo build --quiet --release --no-default-features \
      --target thumbv7em-none-eabihf --example bench_board --target-dir "$dir" 2>"$out_dir/$name.build.txt" \
      || { cat "$out_dir/$name.build.txt" >&2; exit 1; }
  fi
  "${qemu[@]}" "$dir/thumbv7em-none-eabihf/release/examples/bench_board" >"$out_dir/$name.txt"
  grep -q "^DONE ok" "$out_dir/$name.txt" || { cat "$out_dir/$name.txt" >&2; exit 1; }
}
run_build default ""
run_build vmla "-C target-feature=-slowfpvmlx"

rustc_v=$(rustc --version)
qemu_v=$(qemu-system-arm --version | head -1)
python3 - "$out_dir" "$update" "$rustc_v" "$qemu_v" <<'EOF'
import re, sys
out_dir, update, rustc_v, qemu_v = sys.argv[1], sys.argv[2] == "1", sys.argv[3], sys.argv[4]
def load(name):
    r = {}
    for l in open(f"{out_dir}/{name}.txt"):
        m = re.match(r"RESULT (\S+)\s+m=(\d+) (\S+)\s+n=(\d+)\s+ticks=(\d+)", l)
        if m:
            impl, mm, mode, n, t = m.group(1), int(m.group(2)), m.group(3), int(m.group(4)), int(m.group(5))
            r[(impl, mm, mode, n)] = 40 * t  # instructions
    return r
res = {b: load(b) for b in ("default", "vmla")}
def cols(r, impl, m):
    blk = r[(impl, m, "block", 1024)] / 1024
    marg = (r[(impl, m, "block", 1024)] - r[(impl, m, "block", 512)]) / 512
    call = r[(impl, m, "call", 1024)] / 1024
    empty = r[("empty", 0, "call", 1024)] / 1024
    return blk, marg, call, call - empty
lines = []
lines.append("## Board (Cortex-M4, QEMU)")
lines.append("")
lines.append("Instructions per sample of the `f32` compensator (`unlag`: `CascadeCoefficients::process`,")
lines.append("m/2 second-order sections of the exported design) beside the `idsp` 0.23 crate's")
lines.append("`Cascade<[Biquad<f32>; m/2]>` on the same coefficients and samples, in the same QEMU run,")
lines.append("and the fixed-point compensator of issue 4 (`fixed`: `unlag::fixed::FixedCascade::process`,")
lines.append("the same sections planned by `unlag::design::quantise::FixedPlan`, Q1.31 input codes of 1000 Pa),")
lines.append("its cheaper direct form of issue 16 (`direct`: `unlag::fixed::direct::DirectCascade::process`,")
lines.append("planned by `unlag::design::quantise::DirectPlan`) and, on the direct form's integers, idsp's")
lines.append("fixed-point cascade (`idspq`: `Cascade<[Biquad<Q32<30>>; m/2]>`).")
lines.append("Cortex-M4F code (`target-cpu=cortex-m4`, fat LTO, opt-level 3) on `qemu-system-arm -M")
lines.append("mps2-an386 -icount shift=0`; SysTick on the CPU clock counts 40 instructions per tick,")
lines.append("windows of 1024 samples (error under 0.04 per sample). *block*: one call over 1024 samples;")
lines.append("*marginal*: (I1024 - I512)/512, the loop alone; *call*: 1024 out-of-line calls, one sample")
lines.append("each, state by `&mut` (ISR style), the caller's loop included, as in the issue's reference")
lines.append("figures; *call - empty*: minus the same loop calling an empty function (which itself costs 6:")
lines.append("frame push/mov/pop, and `black_box`'s vpush/mov/vpop). Every output is checked against an")
lines.append("f64 reference on the board.")
lines.append("")
lines.append("Command: `bash bench/board.sh --update` (" + rustc_v + ", " + qemu_v + ").")
lines.append("")
lines.append("| build | m | impl | block | marginal | call | call - empty |")
lines.append("|---|---|---|---|---|---|---|")
for b, label in (("default", "default (VMUL + VADD)"), ("vmla", "`-slowfpvmlx` (VMLA)")):
    for m in (2, 4, 8):
        for impl in ("unlag", "idsp", "fixed", "direct", "idspq"):
            blk, marg, call, net = cols(res[b], impl, m)
            lines.append(f"| {label} | {m} | {impl} | {blk:.2f} | {marg:.2f} | {call:.2f} | {net:.2f} |")
for b, label in (("default", "default (VMUL + VADD)"), ("vmla", "`-slowfpvmlx` (VMLA)")):
    e = res[b][("empty", 0, "call", 1024)] / 1024
    lines.append(f"| {label} | - | empty call | - | - | {e:.2f} | 0 |")
for b, label in (("default", "default (VMUL + VADD)"), ("vmla", "`-slowfpvmlx` (VMLA)")):
    key = ("nonlin", 4, "call", 1024)
    if key in res[b]:
        n = res[b][key] / 1024
        e = res[b][("empty", 0, "call", 1024)] / 1024
        lines.append(f"| {label} | 4 | unlag + nonlinear-damping correction | - | - | {n:.2f} | {n - e:.2f} |")
    key = ("bank", 4, "call", 1024)
    if key in res[b]:
        n = res[b][key] / 1024
        e = res[b][("empty", 0, "call", 1024)] / 1024
        lines.append(f"| {label} | 4 | unlag through a temperature bank | - | - | {n:.2f} | {n - e:.2f} |")
lines.append("")
lines.append("Goals for m = 4 (issue 5): f32 at most 30 per single-sample call and at most 14 per")
d4 = cols(res["default"], "unlag", 4); v4 = cols(res["vmla"], "unlag", 4)
i4 = cols(res["default"], "idsp", 4)
lines.append(f"sample in a block: met, call {d4[2]:.2f} ({d4[3]:.2f} beyond the empty call), block {d4[0]:.2f}")
lines.append(f"(marginal {d4[1]:.2f}); idsp in the same run: call {i4[2]:.2f}, block {i4[0]:.2f}. The f32 cascade")
lines.append("runs hand-scheduled Thumb-2 kernels on this target (`src/board/compensator/m4_kernels.s`, written")
lines.append("by `bench/gen_m4_kernels.py`): one VLDM for all coefficients and one for the state, 5")
lines.append("VMLA/VMLS/VMUL per section, one VSTM, no stack frame: 15 instructions for m = 4, the rest")
lines.append("of the call is the caller's loop (10) and the example's out-of-line wrapper (4, a tail")
lines.append("call). In a block, coefficients and states stay in registers, and each section's")
lines.append("registers rotate roles (s1, s2, scratch) from sample to sample, so the loop moves")
lines.append("nothing. With one or two sections (m = 2, 4) the loop is six samples long: one VLDM reads")
lines.append("six inputs, the last section rotates six registers so that its outputs stay in consecutive")
lines.append("registers, and two VSTMs write them back: 5 per section per sample plus 5 per six samples")
lines.append(f"(block {d4[0]:.2f} for m = 4, the issue 16 goal of at most 11 met). With three or four")
lines.append("sections the registers allow three samples a pass: 1 load + 5 per section + 1 store per")
lines.append("sample, plus 2 per three samples for the loop. The kernels do not depend on the build")
lines.append("flags, which is why both builds give the same unlag rows. Bit-exact: VMLA/VMLS round the")
lines.append("product, then the sum (not fused), in the portable code's order; `host-tests/firmware.rs`")
lines.append("checks 1 to 4 sections, per call and in blocks of every length modulo 6, against the host")
lines.append("in QEMU. The single call (issue 16 asks at most 25) is")
lines.append(f"{d4[2]:.2f}, of which {res['default'][('empty', 0, 'call', 1024)] / 1024:.2f} is this harness's empty call; idsp's call in the same harness is")
lines.append(f"{i4[2]:.2f}, so the ratio is {d4[2] / i4[2]:.2f} where the issue's goal (25 against idsp's 45 in its harness)")
lines.append("is 0.56: met as a ratio, not in absolute instructions of this harness; the kernel itself")
lines.append("is 15 instructions (2 VLDM, 10 arithmetic, VSTM, VMOV, BX).")
lines.append("Cycles are not instructions: on the M4, VMLA/VMLS take 3 cycles against 1 + 1 for VMUL +")
lines.append("VADD, so per sample for m = 4 the kernel's arithmetic takes 26 cycles (8 VMLA/VMLS, 2")
lines.append("VMUL) where VMUL + VADD code takes 18; the kernel wins back loads (VLDM: 1 + n cycles")
lines.append("against 2 per VLDR) and the frame. With VMUL + VADD the block loop would need about 21")
lines.append("instructions per sample: the 14-instruction goal needs multiply-accumulate, and fused")
lines.append("VFMA would change the bits.")
nl = res["default"].get(("nonlin", 4, "call", 1024))
if nl is not None:
    lines.append("")
    lines.append(f"With the `nonlinear-damping` effect (issue 7) the board adds `gain * lowpass(|dy| dy)` to the")
    lines.append(f"m = 4 compensator's output: {nl / 1024:.2f} per call in all, against {d4[2]:.2f} without it (the")
    lines.append("correction is the rate term and a second cascade, its own two-section low-pass, through")
    lines.append("the same kernels).")
bk = res["default"].get(("bank", 4, "call", 1024))
if bk is not None:
    lines.append("")
    lines.append(f"Through a `TemperatureBank` (issue 7's `temperature` on the board: the coefficient set for")
    lines.append(f"the measured gas temperature, with a warm-up handover) the m = 4 call takes {bk / 1024:.2f}, against")
    lines.append(f"{d4[2]:.2f} for the bare cascade: the set lookup and the warm-up bookkeeping.")
f4 = cols(res["default"], "fixed", 4)
f2 = cols(res["default"], "fixed", 2)
lines.append("")
lines.append(f"Fixed point, m = 4 (goal: at most 36 per call): call {f4[2]:.2f}, block {f4[0]:.2f} (from 222 and")
lines.append("215 with the compiled Rust), through a hand-written Thumb-2 kernel (`src/board/fixed/m4_fixed.s`,")
lines.append("SMULL/SMLAL, SSAT) with the same arithmetic, bit for bit (QEMU test, including a case")
lines.append("that saturates states and outputs). The goal is not met, and cannot be with the form issue")
sec = f4[2] - f2[2]
lines.append(f"4 requires. Measured: {sec:.0f} per section and {f2[2] - sec:.0f} per call besides (caller's loop,")
lines.append("wrapper, register saves). A section is 9 multiplies (three 64-bit dot products of 3")
lines.append("terms: the M4 has no 32 x 32 dual multiply-accumulate), 2 x 8 for the two states")
lines.append("(magnitude truncation: sign bias, 64-bit add, extract; saturation test: SSAT, compare,")
lines.append("branch), 15 for the output (a runtime shift of 1..62 bits, rounding, saturation test),")
lines.append("8 loads of 10 coefficients and 2 states, 1 store, 3 of loop. A floor for two sections,")
lines.append("counting only the 18 multiplies and 5 instructions for each of the 6 truncations or")
lines.append("roundings with their saturation tests, is 48 before any load, store or call: 36 is out")
lines.append("of reach for this form on this core. idsp's `Q32<30>` biquad (41 per call in the issue's")
lines.append("reference) does 5 multiplies per section in direct form, truncates towards minus")
lines.append("infinity and wraps instead of saturating: exactly the three guarantees of issue 4 (pole")
lines.append("accuracy near z = 1, no limit cycles, overflow flag) that cost the difference. Reaching")
lines.append("about 36 would take giving them up (a direct-form Q31 biquad, or SMMLAR-style 32-bit")
lines.append("products that are not exact), or an FPU: the f32 path above meets its goals.")
r4 = cols(res["default"], "direct", 4)
q4 = cols(res["default"], "idspq", 4)
r2 = cols(res["default"], "direct", 2)
r8 = cols(res["default"], "direct", 8)
lines.append("")
lines.append(f"Direct form (issue 16 item 4; goal for m = 4: at most 40 per sample in a block, at most 55")
lines.append(f"per call): block {r4[0]:.2f}, call {r4[2]:.2f}: met; idsp's `Q32<30>` cascade on the same")
lines.append(f"integers in the same run: block {q4[0]:.2f}, call {q4[2]:.2f}. Direct-form-I biquads with")
lines.append("first-order error feedback (`src/board/fixed/direct/m4_direct.s`, written by")
lines.append("`bench/gen_m4_direct.py`): per section one LDM of the coefficients (two in a block), one")
lines.append("LDM and one STM of the state, 5 SMLAL seeded with the carried truncation residual, SSAT of")
lines.append("the high word (clamp and sticky Q flag), LSR + ORR for the output, BFC for the residual:")
lines.append(f"{r4[0] - r2[0]:.0f} per section and sample in a block. Overflow is read once per call or block from")
lines.append("the Q flag. The trade against the normal form (accuracy, limit cycles) is in the table of")
lines.append("\"Fixed point: the two forms\" below.")
text = "\n".join(lines) + "\n"
print(text)
open(f"{out_dir}/table.md", "w").write(text)
if update:
    path = "BENCHMARKS.md"
    try:
        old = open(path).read()
    except FileNotFoundError:
        old = "# Benchmarks\n"
    head = "## Board (Cortex-M4, QEMU)"
    if head in old:
        start = old.index(head)
        # The generated text ends at the next heading of any level: subsections written by
        # hand or by other commands (the Cortex-M3 table) are kept.
        ends = [i for i in (old.find("\n## ", start + len(head)),
                            old.find("\n### ", start + len(head))) if i >= 0]
        nxt = min(ends) if ends else -1
        new = old[:start] + text + ("\n" + old[nxt + 1:] if nxt >= 0 else "")
    else:
        new = old.rstrip("\n") + "\n\n" + text
    tmp = path + ".tmp"
    open(tmp, "w").write(new)
    import os
    os.replace(tmp, path)
    print(f"updated {path}")
EOF
