#!/usr/bin/env bash
# The test command of README.md: set-up, formatting, lints, every test (the Python module's too),
# and Graphviz checks.
set -euo pipefail
cd "$(dirname "$0")/.."
bash .ci/setup.sh
# A one-shot build gains nothing from incremental state (5 GB of CI's target folder).
export CARGO_INCREMENTAL=0
echo "disk before the build: $(df -h --output=avail . | tail -1 | tr -d ' ') free"
# The target folder reaches about 4 GB (docs/RESULTS.md, "CI's disk"); less room than that ends
# in a linker's bus error or "No space left on device" far into the build.
if [ "$(df --output=avail -k . | tail -1)" -lt $((6 * 1024 * 1024)) ]; then
  echo "warning: less than 6 GB free here; the build and tests need about 4 GB for target/" >&2
fi

cargo fmt --all -- --check
cargo clippy --workspace --all-targets -- -D warnings
cargo build --workspace --all-targets
# The MPI build (`--features mpi`): only the parallax crate is built again.
cargo clippy -p parallax --all-targets --features mpi -- -D warnings

# Every golden DOT must render without a single Graphviz warning.
for f in tests/golden/*.dot; do
  warnings=$(dot -Tsvg "$f" -o /dev/null 2>&1)
  if [ -n "$warnings" ]; then
    echo "error: Graphviz warned on $f:" >&2
    echo "$warnings" >&2
    exit 1
  fi
done
echo "rendered $(ls tests/golden/*.dot | wc -l) golden DOT files without warnings"

# A big schedule's summary drawing renders in seconds (its full drawing, 9 MB, does not finish).
target/debug/parallax -q plan --lf multiscopic --gpus 8 --scheme fine-all --dot-detail summary --dot - \
  | timeout 60 dot -Tsvg -o /dev/null
echo "rendered the summary DOT of multiscopic on 8 devices under fine-all"

# Every test run's output also goes to a log, so the script can close with one total line.
log=$(mktemp)
trap 'rm -f "$log"' EXIT
cargo test --workspace --all-targets --no-fail-fast 2>&1 | tee -a "$log"
cargo test --workspace --doc 2>&1 | tee -a "$log"
# Renders over three MPI ranks (mpirun --oversubscribe on CI's two cores) against one process,
# under multi-source and the two fine schemes; a rank that fails and one that falls silent,
# each also under fine-all (their 60 s --rank-timeout is most of the time); and the MPI
# messages' unit tests.
cargo test -p parallax --features mpi --test cli_ranks 2>&1 | tee -a "$log"
# Every shell block of README.md and docs/ as written, at tiny sizes (its MPI block needs the
# MPI build); their Python blocks run with the module's tests below.
cargo test -p parallax --features mpi --test docs_blocks 2>&1 | tee -a "$log"
cargo test -p parallax-render --features mpi --lib ranks::mpi 2>&1 | tee -a "$log"

# Tests on Sponza read its path from PARALLAX_SPONZA and are #[ignore]d without it; CI has the
# shared scenes beside the clone.
sponza="${PARALLAX_SPONZA:-$(pwd)/../shared/scenes/sponza/Sponza.gltf}"
if [ -f "$sponza" ]; then
  PARALLAX_SPONZA="$sponza" cargo test --workspace --all-targets -- --ignored 2>&1 | tee -a "$log"
else
  echo "Sponza not found at $sponza: its tests stay ignored (set PARALLAX_SPONZA to run them)"
fi

# The Python module: built into the set-up's venv from the workspace's target folder (the dev
# profile of the builds above), then its tests, which compare it with target/debug/parallax.
venv="$(pwd)/target/python-venv"
VIRTUAL_ENV="$venv" CARGO_TARGET_DIR="$(pwd)/target" "$venv/bin/maturin" develop -q -m python/Cargo.toml
"$venv/bin/python" -m pytest python/tests 2>&1 | tee -a "$log"

echo "disk after the tests: $(df -h --output=avail . | tail -1 | tr -d ' ') free, target $(du -sh target | cut -f1)"

# cargo's `test result: ok. N passed; M failed; …` lines, and pytest's `N passed, M failed in Ts`.
awk '/^test result:/ { passed += $4; failed += $6; next }
     / in [0-9.]+s/ { for (i = 2; i <= NF; i++) { if ($i ~ /^passed/) passed += $(i-1); if ($i ~ /^(failed|errors?)/) failed += $(i-1) } }
     END { printf "tests: %d passed, %d failed\n", passed, failed }' "$log"
