#!/bin/bash
# The benchmark on a Ray cluster of two nodes on this machine (two raylets), against the local
# run, then again with the worker node killed (kill -9) mid-run; prints whether every number of
# results.parquet is equal. Needs Ray ('.[ray]'); stops every Ray process on this machine at the
# end (ray stop --force). Usage: benchmarks/ray_two_nodes.sh [OUT (default bench/ray_two_nodes)]
set -u
OUT=${1:-bench/ray_two_nodes}
P=.venv/bin/python; R=.venv/bin/ray
ARGS="--scenario crowd_noise_0.1..0.3 --methods finetune,ewc,cv --trials 3 --seeds 3 --epochs 12 --no-record --set data.splits.train=40"
mkdir -p "$OUT"
start=$(date +%s)
$P -m sim.bench $ARGS --jobs 2 --out "$OUT/local" --overwrite > "$OUT/local.log" 2>&1
echo "local: rc $? in $(( $(date +%s) - start )) s"
for run in whole killed; do
  $R start --head --port 6390 --num-cpus 1 --include-dashboard false --disable-usage-stats > /dev/null
  $R start --address 127.0.0.1:6390 --num-cpus 1 --disable-usage-stats > /dev/null
  start=$(date +%s)
  $P -m sim.bench $ARGS --backend ray --ray-address 127.0.0.1:6390 --out "$OUT/$run" --overwrite > "$OUT/$run.log" 2>&1 &
  bench=$!
  if [ "$run" = killed ]; then
    sleep 25
    worker=$(ps -eo pid,cmd --sort=start_time | grep "[r]aylet/raylet" | tail -1 | awk '{print $1}')
    pkill -9 -P "$worker"; kill -9 "$worker"
    echo "killed the worker node's raylet ($worker) and its workers 25 s in"
  fi
  wait $bench; echo "$run: rc $? in $(( $(date +%s) - start )) s"
  $R stop --force > /dev/null 2>&1
done
$P - "$OUT" <<'PY'
import sys

import numpy as np
import pandas as pd
out = sys.argv[1]
local = pd.read_parquet(f"{out}/local/results.parquet")
keys = [c for c in local.columns if c != "value"]
for run in ("whole", "killed"):
    other = pd.read_parquet(f"{out}/{run}/results.parquet")
    both = local.merge(other, on=keys, suffixes=("", "_ray"))
    equal = np.array_equal(both["value"].to_numpy(), both["value_ray"].to_numpy(), equal_nan=True)
    same = len(both) == len(local) == len(other) and equal  # NaN: a cell that does not exist
    print(f"{run}: {len(other)} numbers, {'equal to' if same else 'NOT equal to'} the local run's")
PY
