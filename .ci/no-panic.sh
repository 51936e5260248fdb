#!/usr/bin/env bash
# Proves on the built firmware that the compensator's per-sample path cannot panic: builds
# examples/bench_board.rs for thumbv7em-none-eabihf, disassembles the ELF, follows every
# direct call and tail branch from the out-of-line per-sample functions (`call_unlag<K>`, one
# sample with state by reference, and `block_unlag<K>`, a block, for K = 1, 2, 4 sections; mangled
# names, one per instantiation), the same for the fixed-point compensator
# (`call_fixed<K>`, `block_fixed<K>`) and of its direct form (`call_direct<K>`,
# `block_direct<K>`), the nonlinear-damping correction (`call_nonlinear`), the
# temperature bank (`call_bank`, `bank_temperature`), from the Cortex-M assembly kernels of the f32 cascade
# (`unlag_m4_cascade_call_N`, `unlag_m4_cascade_block_N`, N = 1..4, which the f32 calls
# branch to) and of the fixed-point cascades (`unlag_m4_fixed_process`, `unlag_m4_direct_call_N`,
# `unlag_m4_direct_block_N`), and from the blob parsers (`parse_blob`, `parse_direct_blob`), and
# fails if any path reaches a panic symbol or an indirect call it cannot follow.
#   bash .ci/no-panic.sh [ELF]     (default: builds the example first)
# NO_PANIC_KERNELS="<symbol prefixes>" names the kernels the ELF must hold (default: the f32,
# fixed and direct-form ones; an FPU-less build has no f32 kernel: "unlag_m4_fixed_ unlag_m4_direct_").
# NO_PANIC_ROOTS=<regex on mangled names> checks other functions instead. As a negative control
# the script first makes sure it sees direct calls into panic code somewhere in the ELF.
set -euo pipefail
cd "$(dirname "$0")/.."
objdump=$(command -v arm-none-eabi-objdump || command -v llvm-objdump || true)
if [ -z "$objdump" ]; then
  echo "no-panic: arm-none-eabi-objdump not found (apt-get install binutils-arm-none-eabi)" >&2
  exit 1
fi
elf=${1:-}
if [ -z "$elf" ]; then
  dir=${CARGO_TARGET_DIR:-target}
  cargo build --quiet --release --no-default-features --target thumbv7em-none-eabihf --example bench_board
  elf="$dir/thumbv7em-none-eabihf/release/examples/bench_board"
fi
"$objdump" -d --no-show-raw-insn "$elf" > "$elf.dis"
check=$(mktemp)
trap 'rm -f "$check"' EXIT
cat > "$check" <<'PY'
import os, re, sys
funcs, cur, edges, indirect, sizes = {}, None, {}, {}, {}
head = re.compile(r"^([0-9a-f]+) <(.+)>:$")
call = re.compile(r"\s(bl|blx|b|b\.w|b\.n|b[a-z]{2}(?:\.[wn])?)\s+[0-9a-f]+ <([^>+]+)(\+0x[0-9a-f]+)?>")
for line in open(sys.argv[1]):
    line = line.rstrip("\n")
    m = head.match(line)
    if m:
        cur = m.group(2)
        edges.setdefault(cur, set()); indirect.setdefault(cur, []); sizes[cur] = 0
        continue
    if cur is None or not re.match(r"^\s+[0-9a-f]+:", line):
        continue
    sizes[cur] += 1
    m = call.search(line)
    if m and m.group(2) != cur:
        edges[cur].add(m.group(2))
    if re.search(r"\s(blx|bx)\s+r(?!14)\d", line) or re.search(r"\smov\s+pc,", line):
        indirect[cur].append(line.strip())
panic = re.compile(r"panic|unwrap_failed|expect_failed|rust_begin_unwind|slice_(start_|end_)?index|bounds_check|unreachable|abort|HardFault", re.I)
root_re = os.environ.get("NO_PANIC_ROOTS", r"\d((call|block)_(unlag|fixed|direct)|call_nonlinear|call_bank|bank_temperature|parse_blob|parse_direct_blob)17h[0-9a-f]{16}E$|^unlag_m4_\w+$")
roots = sorted(f for f in edges if re.search(root_re, f))
if not roots:
    sys.exit("no-panic: no call_unlag/block_unlag function in the ELF (inlined or renamed?)")
kernels = os.environ.get("NO_PANIC_KERNELS", "unlag_m4_cascade_ unlag_m4_fixed_ unlag_m4_direct_").split()
for k in kernels if "NO_PANIC_ROOTS" not in os.environ else []:
    if not any(r.startswith(k) for r in roots):
        sys.exit(f"no-panic: no {k}* kernel in the ELF (the compensator is not using it?)")
# Negative control: calls into panic code must be visible to this parser, or it proves nothing.
callers = sorted(f for f in edges if not panic.search(f) and any(panic.search(g) for g in edges[f]))
if not callers:
    sys.exit("no-panic: no call to a panic symbol seen anywhere in the ELF: the check would be blind")
print(f"negative control: {len(callers)} functions call panic code directly, e.g. {callers[0]}")
bad = False
for root in roots:
    seen, stack, parent = {root}, [root], {}
    while stack:
        f = stack.pop()
        if panic.search(f) and f != root:
            path = [f]
            while path[-1] in parent:
                path.append(parent[path[-1]])
            print("PANIC PATH: " + " <- ".join(path)); bad = True
        if indirect.get(f):
            print(f"INDIRECT CALL in {f}: {indirect[f][0]}"); bad = True
        for g in edges.get(f, ()):
            if g not in seen:
                seen.add(g); parent[g] = f; stack.append(g)
    reach = sorted(seen - {root})
    print(f"{root}: {sizes[root]} instructions, calls {reach if reach else 'nothing'}: no panic reachable")
if bad:
    sys.exit("no-panic: FAILED")
print("no-panic: ok")
PY
python3 "$check" "$elf.dis"
