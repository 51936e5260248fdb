# Sourced by bench/run-fit.sh and bench/run-memory.sh (from the repository root): the Python venv
# under target/ with numpy and scipy (bench/ only: the crate has no Python), the release `unlag`
# binary, and `fit_data N`, which writes the N-row step and validation tests of
# bench/fit_baseline.py into target/bench-fit/N once.
root=$PWD
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target}"
venv="$root/target/bench-venv"
out="$root/target/bench-fit"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check numpy==2.4.6 scipy==1.17.1
cargo build --release --bin unlag
unlag="$CARGO_TARGET_DIR/release/unlag"

fit_data() { # N: the data directory for N rows, written if missing
  local dir="$out/$1"
  if [ ! -f "$dir/est.csv" ]; then
    "$venv/bin/python" bench/fit_baseline.py gen "$1" "$dir" >&2
  fi
  echo "$dir"
}
