#!/bin/bash
# The benchmark on a Ray cluster of two nodes, against the local run, then again with the worker
# node killed (kill -9) mid-run; prints whether every number of results.parquet is equal.
#
# The two nodes are two hosts on this machine: network namespaces of their own (c2i-head at
# 10.77.0.1, c2i-worker at 10.77.0.2) joined by a virtual cable, so the cluster talks over a
# network as two machines do, and nothing it serves is reachable from outside. Ray's token
# authentication is on (RAY_AUTH_MODE=token, a fresh token in OUT, read by the head, the worker
# and the driver), and a driver with a wrong token is shown refused in one line.
# The script stops only what it started: the processes inside its two namespaces, then the
# namespaces. Needs root (ip netns) and Ray ('.[ray]').
# Usage: benchmarks/ray_two_nodes.sh [OUT (default bench/ray_two_nodes)]
set -u
OUT=$(realpath -m "${1:-bench/ray_two_nodes}")
P=$PWD/.venv/bin/python; R=$PWD/.venv/bin/ray
HEAD=c2i-head-$$; WORKER=c2i-worker-$$
ARGS="--scenario crowd_noise_0.1..0.3 --methods finetune,ewc,cv --trials 3 --seeds 3 --epochs 12 --no-record --set data.splits.train=40"
mkdir -p "$OUT"

stop_ours() {  # every process in our namespaces, then the namespaces (nothing else is touched)
  for ns in "$HEAD" "$WORKER"; do
    pids=$(ip netns pids "$ns" 2>/dev/null)
    [ -n "$pids" ] && kill -9 $pids 2>/dev/null
    ip netns del "$ns" 2>/dev/null
  done
  rm -rf "/tmp/$HEAD" "/tmp/$WORKER"
}
trap stop_ours EXIT

hosts() {  # two namespaces, a veth pair between them, each with its loopback up
  ip netns add "$HEAD" && ip netns add "$WORKER" || exit 1
  ip link add "h$$" type veth peer name "w$$"
  ip link set "h$$" netns "$HEAD"; ip link set "w$$" netns "$WORKER"
  ip -n "$HEAD" addr add 10.77.0.1/24 dev "h$$"; ip -n "$WORKER" addr add 10.77.0.2/24 dev "w$$"
  for ns in "$HEAD" "$WORKER"; do ip -n "$ns" link set lo up; done
  ip -n "$HEAD" link set "h$$" up; ip -n "$WORKER" link set "w$$" up
}

export RAY_AUTH_MODE=token RAY_AUTH_TOKEN_PATH="$OUT/auth_token"
(umask 077; $P -c "import secrets; print(secrets.token_hex(32), end='')" > "$RAY_AUTH_TOKEN_PATH")

start=$(date +%s)
$P -m sim.bench $ARGS --jobs 2 --out "$OUT/local" --overwrite > "$OUT/local.log" 2>&1
echo "local: rc $? in $(( $(date +%s) - start )) s"
for run in whole killed; do
  hosts
  ip netns exec "$HEAD" $R start --head --node-ip-address 10.77.0.1 --port 6390 --num-cpus 1 \
    --include-dashboard false --disable-usage-stats --temp-dir "/tmp/$HEAD" > "$OUT/$run-head.log" 2>&1
  ip netns exec "$WORKER" $R start --address 10.77.0.1:6390 --node-ip-address 10.77.0.2 \
    --num-cpus 1 --disable-usage-stats --temp-dir "/tmp/$WORKER" > "$OUT/$run-worker.log" 2>&1
  if [ "$run" = whole ]; then  # a driver without the cluster's token: refused in one line
    echo -n "wrong token" > "$OUT/wrong_token"
    RAY_AUTH_TOKEN_PATH="$OUT/wrong_token" ip netns exec "$HEAD" $P -m sim.bench $ARGS \
      --backend ray --ray-address 10.77.0.1:6390 --out "$OUT/refused" --overwrite > "$OUT/refused.log" 2>&1
    echo "wrong token: rc $?, $(grep -c Traceback "$OUT/refused.log") tracebacks: $(grep '^error' "$OUT/refused.log")"
  fi
  start=$(date +%s)
  ip netns exec "$HEAD" $P -m sim.bench $ARGS --backend ray --ray-address 10.77.0.1:6390 \
    --out "$OUT/$run" --overwrite > "$OUT/$run.log" 2>&1 &
  bench=$!
  if [ "$run" = killed ]; then
    sleep 25
    victims=$(ip netns pids "$WORKER" | wc -l)
    kill -9 $(ip netns pids "$WORKER")
    echo "killed the worker node (its raylet and workers: $victims processes) 25 s in"
  fi
  wait $bench; echo "$run: rc $? in $(( $(date +%s) - start )) s"
  stop_ours
done
$P - "$OUT" <<'PY'
import sys

import numpy as np
import pyarrow.parquet as pq

out = sys.argv[1]
local = pq.read_table(f"{out}/local/results.parquet").to_pylist()
def keyed(rows):
    return {tuple((k, v) for k, v in row.items() if k != "value"): row["value"] for row in rows}
reference = keyed(local)
for run in ("whole", "killed"):
    other = keyed(pq.read_table(f"{out}/{run}/results.parquet").to_pylist())
    same = other.keys() == reference.keys() and np.array_equal(
        [reference[k] for k in reference], [other[k] for k in reference], equal_nan=True
    )
    print(f"{run}: {len(other)} numbers, {'equal to' if same else 'NOT equal to'} the local run's")
PY
