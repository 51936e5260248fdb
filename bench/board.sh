#!/usr/bin/env bash
# Board budget: instructions per sample of the f32 and fixed-point compensators on a Cortex-M4F in QEMU
# (mps2-an386, -icount shift=0, SysTick at 40 instructions per tick), m = 2, 4, 8, one call
# per sample and block mode, with the idsp crate and CMSIS-DSP measured in the same run as the
# baselines.
#
#   bash bench/board.sh            # prints the Markdown table (BENCH_BOARD_CMSIS=0: without CMSIS-DSP)
#   bash bench/board.sh --update   # also replaces the "## Board (Cortex-M4, QEMU)" section
#                                  # of BENCHMARKS.md and its row in the summary table at
#                                  # the top (and nothing else in it)
#
# Two builds of examples/bench_board.rs, both target-cpu=cortex-m4:
#   default: the flags in .cargo/config.toml (LLVM keeps VMUL and VADD apart on the M4), and
#            CMSIS-DSP linked in (--cfg unlag_bench_cmsis, examples/bench_board/cmsis.rs);
#   vmla:    -C target-feature=-slowfpvmlx, which lets LLVM use VMLA/VMLS (chained
#            multiply-accumulate: the same rounding, so bit-identical results; fewer
#            instructions, but 3 cycles each on the M4 against 1 + 1 for VMUL + VADD).
#            Only the compiled code (idsp) changes: unlag's kernels are assembly.
#
# CMSIS-DSP is fetched and built here, never committed: its C sources from the PyPI sdist of
# the `cmsisdsp` Python package (pip download), the CMSIS Core headers it includes
# (cmsis_compiler.h, cmsis_gcc.h) from the crates.io package cmsis_dsp_sys_pregenerated
# (ARM.CMSIS.5.7.0/CMSIS/Include; cargo fetch, nothing of it is built), compiled with
# arm-none-eabi-gcc (installed with apt-get when missing) into
# $CARGO_TARGET_DIR/bench-board/cmsis/libcmsisbench.a.
# Needs: qemu-system-arm, rustup target thumbv7em-none-eabihf, python3 with pip, network
# access to PyPI and crates.io on the first run.
set -euo pipefail
cd "$(dirname "$0")/.."
update=0
[ "${1:-}" = "--update" ] && update=1

root=${CARGO_TARGET_DIR:-target}
out_dir="$root/bench-board"
mkdir -p "$out_dir"

# CMSIS-DSP: the biquad cascades the firmware calls, as a static library.
cmsis_version=1.10.3              # PyPI cmsisdsp
core_crate=cmsis_dsp_sys_pregenerated core_crate_version=0.1.0
cmsis_cflags="-O3 -mthumb -mcpu=cortex-m4 -mfpu=fpv4-sp-d16 -mfloat-abi=hard -DARM_MATH_CM4 -DARM_MATH_LOOPUNROLL"
cmsis_files="arm_biquad_cascade_df2T_f32 arm_biquad_cascade_df2T_init_f32
  arm_biquad_cascade_df1_f32 arm_biquad_cascade_df1_init_f32
  arm_biquad_cascade_df1_q31 arm_biquad_cascade_df1_init_q31
  arm_biquad_cascade_df1_32x64_q31 arm_biquad_cascade_df1_32x64_init_q31"
cmsis_dir=$(mkdir -p "$out_dir/cmsis" && cd "$out_dir/cmsis" && pwd)
build_cmsis() { # every step checked: this runs where `set -e` does not apply
  export DEBIAN_FRONTEND=noninteractive
  if ! command -v arm-none-eabi-gcc >/dev/null; then
    apt-get install -y -qq gcc-arm-none-eabi >/dev/null \
      || { apt-get update -qq && apt-get install -y -qq gcc-arm-none-eabi >/dev/null; } || return 1
  fi
  if ! python3 -m pip --version >/dev/null 2>&1; then
    apt-get install -y -qq python3-pip >/dev/null \
      || { apt-get update -qq && apt-get install -y -qq python3-pip >/dev/null; } || return 1
  fi
  local src="$cmsis_dir/cmsisdsp-$cmsis_version" core="$cmsis_dir/$core_crate-$core_crate_version"
  if [ ! -f "$src/Include/arm_math.h" ]; then
    # --no-binary for this package only: its build dependencies (numpy, ...) come as wheels;
    # pip prepares its metadata, nothing is compiled.
    python3 -m pip download --quiet "cmsisdsp==$cmsis_version" --no-binary cmsisdsp --no-deps \
      -d "$cmsis_dir" >/dev/null || return 1
    tar xzf "$cmsis_dir/cmsisdsp-$cmsis_version.tar.gz" -C "$cmsis_dir" || return 1
  fi
  if [ ! -f "$core/ARM.CMSIS.5.7.0/CMSIS/Include/cmsis_compiler.h" ]; then
    local fetch="$cmsis_dir/fetch" crate
    mkdir -p "$fetch/src" || return 1
    printf '[workspace]\n[package]\nname = "fetch"\nversion = "0.0.0"\nedition = "2021"\n[dependencies]\n%s = "=%s"\n' \
      "$core_crate" "$core_crate_version" >"$fetch/Cargo.toml" || return 1
    echo 'fn main() {}' >"$fetch/src/main.rs" || return 1
    (cd "$fetch" && cargo fetch --quiet) || return 1
    crate=$(ls "${CARGO_HOME:-$HOME/.cargo}"/registry/cache/*/"$core_crate-$core_crate_version.crate" | head -1)
    tar xzf "$crate" -C "$cmsis_dir" --wildcards "*/ARM.CMSIS.5.7.0/CMSIS/Include/cmsis_*.h" || return 1
  fi
  local objs=() f
  for f in $cmsis_files; do
    # shellcheck disable=SC2086
    arm-none-eabi-gcc $cmsis_cflags -I"$src/Include" -I"$src/PrivateInclude" \
      -I"$core/ARM.CMSIS.5.7.0/CMSIS/Include" -c "$src/Source/FilteringFunctions/$f.c" -o "$cmsis_dir/$f.o" \
      || return 1
    objs+=("$cmsis_dir/$f.o")
  done
  rm -f "$cmsis_dir/libcmsisbench.a"
  arm-none-eabi-ar rcs "$cmsis_dir/libcmsisbench.a" "${objs[@]}" || return 1
}
# Without CMSIS-DSP (no network on the first run, say) the table is printed without its rows;
# --update needs them.
cmsis_rustflags="--cfg unlag_bench_cmsis -L native=$cmsis_dir"
if [ "${BENCH_BOARD_CMSIS:-1}" = 0 ] && [ "$update" != 1 ]; then
  # CI checks the budget only: no baseline to fetch.
  echo "board.sh: BENCH_BOARD_CMSIS=0: measuring without CMSIS-DSP" >&2
  cmsis_rustflags=""
elif ! build_cmsis >"$out_dir/cmsis.build.txt" 2>&1; then
  cat "$out_dir/cmsis.build.txt" >&2
  if [ "$update" = 1 ]; then
    echo "board.sh: CMSIS-DSP could not be fetched or built; --update needs it" >&2
    exit 1
  fi
  echo "board.sh: CMSIS-DSP could not be fetched or built: measuring without it" >&2
  cmsis_rustflags=""
fi
qemu=(qemu-system-arm -M mps2-an386 -nographic -monitor none -serial none
      -semihosting-config enable=on,target=native -icount shift=0 -kernel)
base_flags="-C link-arg=-Tlink.x -C target-cpu=cortex-m4"   # as in .cargo/config.toml

run_build() { # name, extra rustflags (added to those of .cargo/config.toml), in a target dir of its own
  local name=$1 extra=$2 dir="$root/bench-board-$1"
  RUSTFLAGS="$base_flags $extra" cargo build --quiet --release --no-default-features \
    --target thumbv7em-none-eabihf --example bench_board --target-dir "$dir" 2>"$out_dir/$name.build.txt" \
    || { cat "$out_dir/$name.build.txt" >&2; exit 1; }
  "${qemu[@]}" "$dir/thumbv7em-none-eabihf/release/examples/bench_board" >"$out_dir/$name.txt"
  grep -q "^DONE ok" "$out_dir/$name.txt" || { cat "$out_dir/$name.txt" >&2; exit 1; }
}
run_build default "$cmsis_rustflags"
run_build vmla "-C target-feature=-slowfpvmlx"

rustc_v=$(rustc --version)
qemu_v=$(qemu-system-arm --version | head -1)
# When and on what: the date, the commit measured (with -dirty for uncommitted changes) and the host
# (instruction counts do not depend on it, but the toolchain does).
measured="$(date -u +%Y-%m-%d), commit $(git describe --always --dirty 2>/dev/null || echo unknown), $(uname -m) host"
gcc_v=$(arm-none-eabi-gcc --version 2>/dev/null | head -1 || true)
python3 - "$out_dir" "$update" "$rustc_v" "$qemu_v" "$measured" "$gcc_v" "$cmsis_version" "$cmsis_cflags" <<'EOF'
import re, sys
out_dir, update, rustc_v, qemu_v, measured = sys.argv[1], sys.argv[2] == "1", sys.argv[3], sys.argv[4], sys.argv[5]
gcc_v, cmsis_version, cmsis_cflags = sys.argv[6], sys.argv[7], sys.argv[8]
def load(name):
    r = {}
    for l in open(f"{out_dir}/{name}.txt"):
        m = re.match(r"RESULT (\S+)\s+m=(\d+) (\S+)\s+n=(\d+)\s+ticks=(\d+)", l)
        if m:
            impl, mm, mode, n, t = m.group(1), int(m.group(2)), m.group(3), int(m.group(4)), int(m.group(5))
            r[(impl, mm, mode, n)] = 40 * t  # instructions
    return r
res = {b: load(b) for b in ("default", "vmla")}
has_cmsis = ("cmsis", 4, "call", 1024) in res["default"]
# CMSIS-DSP's agreement: the largest |CMSIS f32 - unlag f32| (Pa), |CMSIS Q31 - idsp Q32<30>| and
# |CMSIS Q31 - unlag direct| (codes) over every m and mode, and the largest error against the f64
# reference.
agree, agree_direct, ref_err = {}, {}, {}
for l in open(f"{out_dir}/default.txt"):
    m = re.match(r"CHECK\s+(\S+)\s+m=\d+\s+\S+\s+max\|y - f64 reference\|=(\S+) Pa max\|y - (?:unlag|idspq)\|=(\S+)", l)
    if m:
        name, e, d = m.group(1), float(m.group(2)), float(m.group(3))
        agree[name] = max(agree.get(name, 0.0), d)
        ref_err[name] = max(ref_err.get(name, 0.0), e)
        m = re.search(r"max\|y - direct\|=(\d+) codes", l)
        if m:
            agree_direct[name] = max(agree_direct.get(name, 0), int(m.group(1)))
    m = re.match(r"CHECK\s+(unlag|idsp)\s+m=\d+\s+\S+\s+max\|y - f64 reference\|=(\S+) Pa", l)
    if m:
        ref_err[m.group(1)] = max(ref_err.get(m.group(1), 0.0), float(m.group(2)))
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
lines.append("form (`direct`: `unlag::board::fixed::direct::DirectCascade`), beside two baselines on the same")
lines.append("coefficients and samples in the same run: the `idsp` 0.23 crate (`idsp`:")
lines.append("`Cascade<[Biquad<f32>; m/2]>`; `idspq`: `Cascade<[Biquad<Q32<30>>; m/2]>` on the direct")
lines.append("form's integers) and CMSIS-DSP (`cmsis`: `arm_biquad_cascade_df2T_f32`; `cmsis1`:")
lines.append("`arm_biquad_cascade_df1_f32`; `cmsisq`: `arm_biquad_cascade_df1_q31` and `cmsq64`:")
lines.append("`arm_biquad_cas_df1_32x64_q31`, both on the direct form's integers with `postShift = 1`;")
lines.append("`cmsq64` keeps 64-bit feedback states, CMSIS's high-precision form). Rust: fat LTO,")
lines.append("opt-level 3. CMSIS-DSP: the C sources of the PyPI package `cmsisdsp` " + cmsis_version + ", built by")
lines.append("the script with " + gcc_v.split(" (")[0] + " " + gcc_v.split(") ")[-1] + " `" + cmsis_cflags + "`")
lines.append("and linked into the same firmware (GCC fuses its multiply-adds into VFMA: one instruction,")
lines.append("3 cycles on the M4). `qemu-system-arm -M mps2-an386 -icount shift=0`, windows")
lines.append("of 1024 samples (error under 0.04 per sample). *block*: one call over 1024 samples;")
lines.append("*marginal*: (I1024 - I512)/512; *call*: one out-of-line call per sample (ISR style; CMSIS")
lines.append("with `blockSize = 1`), the caller's loop included; *call - empty*: minus the same loop")
lines.append("calling an empty function. Every output is checked against an f64 reference on the board:")
if has_cmsis:
    lines.append(f"CMSIS's f32 outputs are within {max(agree.get('cmsis', 0), agree.get('cmsis1', 0)):.2g} Pa of unlag's "
             f"(from the f64 reference: CMSIS {max(ref_err.get('cmsis', 0), ref_err.get('cmsis1', 0)):.2g} Pa, "
             f"unlag {ref_err.get('unlag', 0):.2g}, idsp {ref_err.get('idsp', 0):.2g}: f32 rounding), `cmsisq` is "
             + ("bit-identical to `idspq`" if agree.get("cmsisq", 1) == 0 else f"within {agree.get('cmsisq'):.0f} codes of `idspq`")
             + " and `cmsq64` "
             + ("bit-identical to `direct`" if agree_direct.get("cmsq64", 1) == 0
                else f"within {agree_direct.get('cmsq64')} codes of `direct`") + ".")
else:
    lines.append("**CMSIS-DSP was not measured in this run (not wanted, or it could not be fetched or built): its rows are missing.**")
lines.append("")
lines.append("Command: `bash bench/board.sh --update`. Measured " + measured + "; " + rustc_v + ", " + qemu_v + ".")
lines.append("")
lines.append("Each cell: instructions per sample in a block / per call (*block* and *marginal* agree within")
lines.append("0.3; the empty call's loop, included in *call*, costs " + f"{res['default'][('empty', 0, 'call', 1024)] / 1024:.2f}" + ").")
lines.append("")
lines.append("| impl | m = 2 | m = 4 | m = 8 |")
lines.append("|---|---|---|---|")
impls = ("unlag", "idsp", "cmsis", "cmsis1", "fixed", "direct", "idspq", "cmsisq", "cmsq64")
impls = [i for i in impls if has_cmsis or not i.startswith("cms")]
for impl in impls:
    cells = []
    for m in (2, 4, 8):
        blk, marg, call, net = cols(res["default"], impl, m)
        cells.append(f"{blk:.2f} / {call:.2f}")
    lines.append(f"| {impl} | " + " | ".join(cells) + " |")
for key, what in ((("nonlin", 4, "call", 1024), "unlag + nonlinear-damping correction (call)"),
                  (("bank", 4, "call", 1024), "unlag through a temperature bank (call)")):
    if key in res["default"]:
        n = res["default"][key] / 1024
        lines.append(f"| {what} | - | {n:.2f} | - |")
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
c4 = cols(res["default"], "cmsis", 4) if has_cmsis else None
lines.append(f"- f32: at most 30 a call and 11 a sample in a block: call {u4[2]:.2f}, block {u4[0]:.2f}, "
             f"{met(u4[2] <= 30 and u4[0] <= 11)} (idsp: {i4[2]:.2f}, {i4[0]:.2f}"
             + (f"; CMSIS-DSP df2T: {c4[2]:.2f}, {c4[0]:.2f}" if c4 else "") + ").")
lines.append(f"- fixed point, direct form: at most 55 a call and 40 in a block: call {d4[2]:.2f}, block "
             f"{d4[0]:.2f}, {met(d4[2] <= 55 and d4[0] <= 40)}.")
lines.append(f"- fixed point, normal form: at most 36 a call: call {f4[2]:.2f}, {met(f4[2] <= 36)}. Its")
lines.append("  guarantees (pole accuracy near z = 1, no limit cycles, saturation with an overflow flag)")
lines.append("  cost 9 multiplies, two truncations and a rounding with saturation tests per section: at")
lines.append("  least 48 instructions for two sections before any load or store. The direct form trades")
lines.append("  them for speed (see \"Fixed point: the two forms\").")
# One paragraph (or bullet) a line, as the rest of BENCHMARKS.md: the lines above are joined.
merged = []
for l in lines:
    prose = l and not l.startswith(("|", "#", "- "))
    if prose and merged and merged[-1] and not merged[-1].startswith(("|", "#")):
        merged[-1] += " " + l.strip()
    else:
        merged.append(l)
lines = merged
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
    # Its row in the summary table at the top.
    q4 = cols(res["default"], "cmsisq", 4)
    row = ("| Cortex-M4 instructions per sample (QEMU) against idsp and CMSIS-DSP | m = 4, f32: "
           f"{u4[0]:.2f} a sample in a block (idsp {i4[0]:.2f}, CMSIS-DSP {c4[0]:.2f}), {u4[2]:.2f} a call "
           f"(idsp {i4[2]:.2f}, CMSIS-DSP {c4[2]:.2f}); direct-form Q31 {d4[0]:.2f} in a block (CMSIS-DSP "
           f"{q4[0]:.2f}) | [board](#board-cortex-m4-qemu) |")
    new = re.sub(r"^\| Cortex-M4 instructions per sample \(QEMU\) against idsp.*$", lambda _: row, new,
                 count=1, flags=re.M)
    tmp = path + ".tmp"
    open(tmp, "w").write(new)
    import os
    os.replace(tmp, path)
    print(f"updated {path}")
EOF
