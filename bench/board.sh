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
# When and on what: the date, the commit measured (with -dirty for uncommitted changes) and the host
# (instruction counts do not depend on it, but the toolchain does).
measured="$(date -u +%Y-%m-%d), commit $(git describe --always --dirty 2>/dev/null || echo unknown), $(uname -m) host"
python3 - "$out_dir" "$update" "$rustc_v" "$qemu_v" "$measured" <<'EOF'
import re, sys
out_dir, update, rustc_v, qemu_v, measured = sys.argv[1], sys.argv[2] == "1", sys.argv[3], sys.argv[4], sys.argv[5]
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
lines.append("Instructions per sample on a Cortex-M4F: the `f32` compensator (`unlag`:")
lines.append("`CascadeCoefficients::process`, m/2 second-order sections of the exported design), the")
lines.append("fixed-point compensator in normal form (`fixed`: `unlag::board::fixed::FixedCascade`) and in direct")
lines.append("form (`direct`: `unlag::board::fixed::direct::DirectCascade`), beside the `idsp` 0.23 crate on the same")
lines.append("coefficients and samples in the same run (`idsp`: `Cascade<[Biquad<f32>; m/2]>`; `idspq`:")
lines.append("`Cascade<[Biquad<Q32<30>>; m/2]>` on the direct form's integers). Fat LTO, opt-level 3,")
lines.append("`qemu-system-arm -M mps2-an386 -icount shift=0`, windows of 1024 samples (error under 0.04")
lines.append("per sample). *block*: one call over 1024 samples; *marginal*: (I1024 - I512)/512; *call*:")
lines.append("one out-of-line call per sample (ISR style), the caller's loop included; *call - empty*: minus")
lines.append("the same loop calling an empty function. Every output is checked against an f64 reference on")
lines.append("the board. CMSIS-DSP is not measured yet.")
lines.append("")
lines.append("Command: `bash bench/board.sh --update`. Measured " + measured + "; " + rustc_v + ", " + qemu_v + ".")
lines.append("")
lines.append("| m | impl | block | marginal | call | call - empty |")
lines.append("|---|---|---|---|---|---|")
for m in (2, 4, 8):
    for impl in ("unlag", "idsp", "fixed", "direct", "idspq"):
        blk, marg, call, net = cols(res["default"], impl, m)
        lines.append(f"| {m} | {impl} | {blk:.2f} | {marg:.2f} | {call:.2f} | {net:.2f} |")
e = res["default"][("empty", 0, "call", 1024)] / 1024
lines.append(f"| - | empty call | - | - | {e:.2f} | 0 |")
for key, what in ((("nonlin", 4, "call", 1024), "unlag + nonlinear-damping correction"),
                  (("bank", 4, "call", 1024), "unlag through a temperature bank")):
    if key in res["default"]:
        n = res["default"][key] / 1024
        lines.append(f"| 4 | {what} | - | - | {n:.2f} | {n - e:.2f} |")
lines.append("")
vm = {m: cols(res["vmla"], "idsp", m) for m in (2, 4, 8)}
lines.append("With `-C target-feature=-slowfpvmlx` (LLVM may then emit VMLA, 3 cycles each on the M4)")
lines.append("idsp's f32 rows become block " + " / ".join(f"{vm[m][0]:.2f}" for m in (2, 4, 8)) + ", call "
             + " / ".join(f"{vm[m][2]:.2f}" for m in (2, 4, 8)) + " for m = 2 / 4 / 8; unlag's rows do not")
lines.append("change: its kernels are assembly (`src/board/compensator/m4_kernels.s`,")
lines.append("`src/board/fixed/m4_fixed.s`, `src/board/fixed/direct/m4_direct.s`), bit-exact with the")
lines.append("portable code (`host-tests/firmware.rs`).")
lines.append("")
u4, i4 = cols(res["default"], "unlag", 4), cols(res["default"], "idsp", 4)
f4, d4 = cols(res["default"], "fixed", 4), cols(res["default"], "direct", 4)
met = lambda ok: "met" if ok else "not met"
lines.append("Budgets for m = 4:")
lines.append("")
lines.append(f"- f32: at most 30 a call and 11 a sample in a block: call {u4[2]:.2f}, block {u4[0]:.2f}, "
             f"{met(u4[2] <= 30 and u4[0] <= 11)} (idsp: {i4[2]:.2f}, {i4[0]:.2f}).")
lines.append(f"- fixed point, direct form: at most 55 a call and 40 in a block: call {d4[2]:.2f}, block "
             f"{d4[0]:.2f}, {met(d4[2] <= 55 and d4[0] <= 40)}.")
lines.append(f"- fixed point, normal form: at most 36 a call: call {f4[2]:.2f}, {met(f4[2] <= 36)}. Its")
lines.append("  guarantees (pole accuracy near z = 1, no limit cycles, saturation with an overflow flag)")
lines.append("  cost 9 multiplies, two truncations and a rounding with saturation tests per section: at")
lines.append("  least 48 instructions for two sections before any load or store. The direct form trades")
lines.append("  them for speed (see \"Fixed point: the two forms\").")
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
