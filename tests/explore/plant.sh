#!/usr/bin/env bash
# Shows that the explorer can fail (issue 20): applies each planted bug (tests/explore/planted/*.py)
# in a throwaway worktree of HEAD, never in this tree, builds the explorer there and runs fresh
# seeds, the same ones with and without the bug: the runs needed to catch it (`--until-fail`),
# and how many of RUNS fresh runs per variant show the bug's violation (`--kind`; a known,
# tagged finding does not count: a residual risk is no catch).
# Usage: [BUGS=N] tests/explore/plant.sh [RUNS] [--only VARIANT]   (BUGS=1: only bug 1)
#        tests/explore/plant.sh --check   (does each bug still apply? no build, seconds)
set -euo pipefail
root=$(git rev-parse --show-toplevel)
# `plant.sh --check`: only whether every bug still applies to this tree (no build; CI runs it).
if [ "${1:-}" = --check ]; then
  exec python3 "$root/tests/explore/planted/_plant.py" --check "$root"
fi
runs=${1:-3000}
shift || true
tree=$(mktemp -d /tmp/gripper-plant.XXXXXX)
git -C "$root" worktree add --quiet --detach "$tree" HEAD
trap 'git -C "$root" worktree remove --force "$tree"; rm -f "$tree.baseline"' EXIT
# The dependencies are shared with this tree's build; the planted crate builds on its own.
export CARGO_TARGET_DIR="$root/target/planted"
explorer() {
  (cd "$tree" && cargo build --quiet --test explore)
  (cd "$tree" && cargo test --quiet --test explore --no-run --message-format=json 2>/dev/null) \
    | sed -n 's/.*"executable":"\([^"]*explore[^"]*\)".*/\1/p' | tail -n 1
}
# Each bug names the violation that catches it (KIND = "..." in its file); the unplanted tree
# runs the same seeds first, so the table can say how often that violation occurs without it.
# The planted builds reuse the same target path, so the unplanted binary is kept aside: without
# the copy, each bug's "without" row would run the previous bug's build.
cp "$(explorer)" "$tree.baseline"
baseline="$tree.baseline"
# BUGS=3 is bug 3 alone, not 30-39 too (bugs are numbered past 9 since issue 29).
pattern=${BUGS:+${BUGS}_*.py}
for bug in "$root"/tests/explore/planted/${pattern:-[0-9]*.py}; do
  name=$(basename "$bug" .py)
  kind=$(sed -n 's/^KIND = "\(.*\)"$/\1/p' "$bug")
  echo "== $name (violation: $kind)"
  echo "-- without the bug:"
  "$baseline" --until-fail "$runs" --kind "$kind" --start 0x91a7 "$@" || true
  "$baseline" --seeds "$runs" --kind "$kind" --start 0x91a7 --no-regressions --determinism 0 \
    --no-shrink "$@" 2>/dev/null | grep -E '^(kind|explore)' || true
  git -C "$tree" checkout --quiet -- .
  if ! (cd "$root/tests/explore/planted" && python3 "$bug" "$tree"); then
    echo "-- not applied"
    continue
  fi
  echo "-- with the bug:"
  planted=$(explorer)
  "$planted" --until-fail "$runs" --kind "$kind" --start 0x91a7 "$@" || true
  "$planted" --seeds "$runs" --kind "$kind" --start 0x91a7 --no-regressions --determinism 0 \
    --no-shrink "$@" 2>/dev/null | grep -E '^(kind|explore)' || true
done
