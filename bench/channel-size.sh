#!/usr/bin/env bash
# Flash and RAM per compensator channel on a Cortex-M4F (thumbv7em-none-eabihf), for the f32
# cascade and the two fixed-point forms (normal and direct) at orders m = 2, 4, 8, with the
# instructions per sample beside each row.
#
#   bash bench/channel-size.sh                # prints the Markdown table
#   bash bench/channel-size.sh --no-budget    # sizes only, without running bench/board.sh
#
# Sizes: bench/channel-size/ (a minimal firmware holding CHANNELS channels of one kind, see its
# src/main.rs) is built with no compensator, then with 1 and 2 channels of each kind and order;
# `arm-none-eabi-size` reads each ELF (flash = text + data, RAM = data + bss). The first
# channel is the difference between 1 channel and none (code, the exported coefficients, the
# validated coefficients in RAM, one state); each further channel the difference between 2
# channels and 1 (the channels share the coefficients). Release profile as unlag's: fat LTO,
# one codegen unit, opt-level 3, target-cpu=cortex-m4 (.cargo/config.toml).
# Instructions per sample: bench/board.sh's QEMU run (its default build), the same
# compensators and coefficients: "call" is one out-of-line call per sample minus the
# harness's empty call, "block" one call over 1024 samples (process_in_place).
# Needs: rustup target thumbv7em-none-eabihf, arm-none-eabi-size (binutils-arm-none-eabi);
# for the instructions, what bench/board.sh needs (qemu-system-arm, python3).
set -euo pipefail
cd "$(dirname "$0")/.."
budget=1
[ "${1:-}" = "--no-budget" ] && budget=0

root=${CARGO_TARGET_DIR:-target}
case "$root" in /*) ;; *) root="$PWD/$root" ;; esac
target_dir="$root/channel-size"
out_dir="$root/channel-size-out"
mkdir -p "$out_dir"
elf="$target_dir/thumbv7em-none-eabihf/release/unlag-channel-size"

# flash and RAM of one build: "<flash> <ram>"
measure() { # features ("" = the baseline)
  (cd bench/channel-size && CARGO_TARGET_DIR="$target_dir" cargo build --quiet --release \
    --target thumbv7em-none-eabihf ${1:+--features "$1"}) 2>"$out_dir/build.txt" \
    || { cat "$out_dir/build.txt" >&2; exit 1; }
  arm-none-eabi-size "$elf" | awk 'NR == 2 { print $1 + $2, $2 + $3 }'
}

sizes="$out_dir/sizes.txt"
echo "baseline - - $(measure "")" > "$sizes"
for kind in f32 fixed direct; do
  for m in 2 4 8; do
    for ch in 1 2; do
      echo "$kind $m $ch $(measure "$kind,m$m,ch$ch")" >> "$sizes"
    done
  done
  # Where the flash of the start goes: the same m = 8 channels started from zero.
  for ch in 1 2; do
    echo "$kind-zero 8 $ch $(measure "$kind,m8,ch$ch,zero-start")" >> "$sizes"
  done
done

budget_file=""
if [ "$budget" = 1 ]; then
  bash bench/board.sh > "$out_dir/board.txt"
  budget_file="$root/bench-board/default.txt"
fi

rustc_v=$(rustc --version)
python3 - "$sizes" "$budget_file" "$rustc_v" <<'EOF'
import re, sys
sizes_path, budget_path, rustc_v = sys.argv[1], sys.argv[2], sys.argv[3]
sizes = {}
for line in open(sizes_path):
    kind, m, ch, flash, ram = line.split()
    sizes[(kind, m, ch)] = (int(flash), int(ram))
base = sizes[("baseline", "-", "-")]
insn = {}
if budget_path:
    for l in open(budget_path):
        r = re.match(r"RESULT (\S+)\s+m=(\d+) (\S+)\s+n=(\d+)\s+ticks=(\d+)", l)
        if r:
            insn[(r.group(1), int(r.group(2)), r.group(3), int(r.group(4)))] = 40 * int(r.group(5))
names = {"f32": ("f32 cascade", "unlag"), "fixed": ("fixed point, normal form", "fixed"),
         "direct": ("fixed point, direct form", "direct")}
print("| arithmetic | m (order) | sections (N = m/2) | first channel: flash | first channel: RAM "
      "| each further channel: flash | each further channel: RAM | insn/sample, call | insn/sample, block |")
print("|---|---|---|---|---|---|---|---|---|")
for kind in ("f32", "fixed", "direct"):
    label, bench = names[kind]
    for m in (2, 4, 8):
        f1, r1 = sizes[(kind, str(m), "1")]
        f2, r2 = sizes[(kind, str(m), "2")]
        call = block = "-"
        if insn:
            empty = insn[("empty", 0, "call", 1024)] / 1024
            call = f"{insn[(bench, m, 'call', 1024)] / 1024 - empty:.1f}"
            block = f"{insn[(bench, m, 'block', 1024)] / 1024:.1f}"
        print(f"| {label} | {m} | {m // 2} | {f1 - base[0]} B | {r1 - base[1]} B "
              f"| {f2 - f1} B | {r2 - r1} B | {call} | {block} |")
print()
print("The same m = 8 channels started with every state zero instead of in equilibrium with the")
print("first reading (`equilibrium` solves each section in f64, software floating point on a")
print("Cortex-M4F; the f32 constructor's f64 work is folded at compile time from the constants):")
print()
print("| arithmetic | m | first channel: flash | first channel: RAM | each further channel: flash | each further channel: RAM |")
print("|---|---|---|---|---|---|")
for kind in ("f32", "fixed", "direct"):
    f1, r1 = sizes[(kind + "-zero", "8", "1")]
    f2, r2 = sizes[(kind + "-zero", "8", "2")]
    print(f"| {names[kind][0]}, zero start | 8 | {f1 - base[0]} B | {r1 - base[1]} B | {f2 - f1} B | {r2 - r1} B |")
print()
print(f"Baseline (cortex-m-rt, the loop, no compensator): flash {base[0]} B, RAM {base[1]} B.")
print("Flash = text + data, RAM = data + bss (arm-none-eabi-size), thumbv7em-none-eabihf,")
print(f"target-cpu=cortex-m4, fat LTO, opt-level 3, {rustc_v}.")
if insn:
    print("Instructions per sample: bench/board.sh (QEMU mps2-an386, -icount shift=0), default build;")
    print("call = one call per sample minus the harness's empty call, block = process_in_place over 1024.")
print("Command: bash bench/channel-size.sh")
EOF
