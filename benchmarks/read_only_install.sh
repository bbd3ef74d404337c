#!/bin/bash
# `make run`'s command from a read-only install with a read-only HOME (issue 64): the checkout
# (its venv included) and HOME bind-mounted read-only in a private mount namespace (root), the
# run writing only to OUT. Prints the command's last lines and its exit code.
# Usage: benchmarks/read_only_install.sh [OUT (default: a temporary folder)]
set -u
ROOT=$(cd "$(dirname "$0")/.." && pwd)
OUT=${1:-$(mktemp -d)}
mkdir -p "$OUT"
unshare -m sh -c '
  mount --bind "$1" "$1" && mount -o remount,bind,ro "$1" &&
  mount --bind "$HOME" "$HOME" && mount -o remount,bind,ro "$HOME" &&
  touch "$1/.probe" 2>/dev/null && echo "the checkout is writable: not a read-only test" && exit 1
  cd "$2" && PYTHONDONTWRITEBYTECODE=1 "$1/.venv/bin/python" -m sim.run \
    --scenario crowd_noise_0.1..0.6 --jobs 2 --set data.splits.train=150 \
    --out "$2/run" --cache "$2/cache"
' sh "$ROOT" "$OUT" > "$OUT/log.txt" 2>&1
rc=$?
tr '\r' '\n' < "$OUT/log.txt" | grep -v "^tasks" | tail -8
echo "exit code $rc; the run in $OUT/run"
