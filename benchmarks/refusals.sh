#!/bin/bash
# Issue 47's and issue 64's reproducers, run against this checkout: each must answer one `error:` line and
# exit 2 (or keep the user's file), never a traceback. Prints one row a case.
#   bash benchmarks/refusals.sh [PYTHON]   (an absolute path: the cases run in a temporary folder)
set -u
PY=${1:-python}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
cd "$W"
row() {  # name, then the command
  local name=$1; shift
  timeout 60 "$@" > out.txt 2> err.txt
  local rc=$? lines tb
  lines=$(grep -v -E '^([[:alnum:] ]+: +[0-9]+%\||domain [0-9]+/[0-9]+ )' err.txt | grep -c .)  # progress aside
  tb=$(grep -c Traceback err.txt)
  printf '%-44s rc=%-3s stderr lines=%-2s tracebacks=%s  %s\n' "$name" "$rc" "$lines" "$tb" \
    "$(grep -m1 error: err.txt | cut -c1-90)"
}
cfg() { printf '%s\n' "$2" > "$1"; }
cfg epochs.toml 'epochs = [1]';                   row "config: epochs = [1]" $PY -m sim.run --config epochs.toml --scenario crowd_noise_0.1
cfg rerun.toml 'rerun = false';                   row "config: rerun = false" $PY -m sim.run --config rerun.toml --scenario crowd_noise_0.1
cfg device.toml 'device = true';                  row "config: device = true" $PY -m sim.run --config device.toml --scenario crowd_noise_0.1
cfg methods.toml $'[methods]\na = 1';             row "config: methods a table" $PY -m sim.run --config methods.toml --scenario crowd_noise_0.1
cfg jobs.toml 'jobs = [1]';                       row "config: jobs = [1]" $PY -m sim.run --config jobs.toml --scenario crowd_noise_0.1
cfg workers.toml 'workers = false';               row "config: workers = false" $PY -m sim.run --config workers.toml --scenario crowd_noise_0.1
mkfifo fifo;                                      row "config: a FIFO" $PY -m sim.run --config fifo --scenario crowd_noise_0.1
row "config: /dev/zero" $PY -m sim.run --config /dev/zero --scenario crowd_noise_0.1
$PY -c "print('a = ' + '['*2000 + ']'*2000)" > deep.toml
row "config: 2,000-deep nesting" $PY -m sim.run --config deep.toml --scenario crowd_noise_0.1
row "scenario: one value twice" $PY -m sim.run --scenario crowd_radius_0.1,00.1 --quick
row "device: cuda: + 20 digits" $PY -m sim.run --scenario crowd_noise_0.1 --device cuda:99999999999999999999
row "cache: 5,000 characters" $PY -m sim.run --scenario crowd_noise_0.1 --quick --cache "$($PY -c "print('c'*5000)")"
row "storage: a bad URL" $PY -m sim.bench --scenario crowd_noise_0.1..0.3 --quick --storage "postgresql://nobody@127.0.0.1:1/x" --out bench1
printf 'SQLite format 3\000 not really' > tuning.db
row "storage: a damaged SQLite file" $PY -m sim.bench --scenario crowd_noise_0.1..0.3 --quick --storage "sqlite:///$W/tuning.db" --out bench2
row "logger: mlflow at a refused port" $PY -m sim.run --scenario crowd_noise_0.1 --quick --logger mlflow=http://127.0.0.1:1 --out run1
mkdir -p tp && printf '{"scene": {"id": 0, "p": 1, "s": 0, "e": 100000000, "fps": 2.5, "tag": 1}}\n{"track": {"f": 0, "p": 1, "x": 0.0, "y": 0.0}}\n' > tp/big.ndjson
printf 'generator = "files"\n[knobs]\nformat = "trajnetpp"\n[values.a]\ntrain = ["tp/big.ndjson"]\ntest = ["tp/big.ndjson"]\n' > tnpp.toml
row "TrajNet++: a scene of 1e8 frames" $PY -m sim.generate --scenarios-dir "$W" --scenario tnpp_a --out gen1 --memory-budget 1
mkdir -p run2 && $PY -m sim.run --scenario crowd_noise_0.1 --quick --methods cv --no-record --out run2 > /dev/null 2>&1
printf '{"trunc' > run2/config.json
row "resume: config.json truncated" $PY -m sim.run --scenario crowd_noise_0.1 --quick --methods cv --no-record --resume --out run2
mkdir -p gen2/src && echo mine > gen2/src/notes.txt && echo '{"domains": [{"name": "src"}]}' > gen2/summary.json
row "generate --overwrite: a summary naming src" $PY -m sim.generate --scenario crowd_noise_0.1 --set data.splits.train=2 --out gen2 --overwrite
printf '%-44s %s\n' "  the user's gen2/src/notes.txt afterwards:" "$(cat gen2/src/notes.txt 2>&1)"
# Issue 64's reproducers (the numbered cases of its audit), on this checkout
cfg gen.toml $'scenario = "crowd_noise_0.1"\n[settings.data]\nagents = 3\n"splits.train" = 4\n"splits.val" = 2\n"splits.test" = 3'
row "5: generate --config [settings.data]" $PY -m sim.generate --config gen.toml --out gen3
printf '%-44s %s\n' "  its summary (3 agents, 4/2/3 expected):" "$($PY -c "import json; d=json.load(open('gen3/summary.json'))['domains'][0]; print(d['knobs']['agents'], d['splits'])" 2>&1)"
mkdir -p run3 && $PY -m sim.run --scenario crowd_noise_0.1..0.2 --quick --methods cv --no-record --out run3 > /dev/null 2>&1
rm -f run3/jobs/cv/seed_0/result.json run3/jobs/cv/seed_0/checkpoints/task_00.pt && mkdir run3/jobs/cv/seed_0/checkpoints/task_00.pt
row "8: a checkpoint replaced by a folder" $PY -m sim.run --scenario crowd_noise_0.1..0.2 --quick --methods cv --no-record --resume --out run3
$PY -c "print('{\"track\": ' * 100000 + '1' + '}' * 100000)" > tp/deep.ndjson
printf 'generator = "files"\n[knobs]\nformat = "trajnetpp"\n[values.a]\ntrain = ["tp/deep.ndjson"]\ntest = ["tp/deep.ndjson"]\n' > deep.toml
row "8: a TrajNet++ line nested 100,000 deep" $PY -m sim.generate --scenarios-dir "$W" --scenario deep_a --out gen4
mkdir -p sd && printf '1.5 0 0 10 10 0 0 0 0 "Pedestrian"\n1.7 0 0 10 10 12 0 0 0 "Pedestrian"\n' > sd/a.txt
printf 'generator = "files"\n[knobs]\nformat = "sdd"\n[values.a]\ntrain = ["sd/a.txt"]\ntest = ["sd/a.txt"]\n' > sdd1.toml
row "8: SDD track ids 1.5 and 1.7" $PY -m sim.generate --scenarios-dir "$W" --scenario sdd1_a --out gen5
printf '{"scene": {"id": 0, "p": 1, "s": 0, "e": 10}}\n{"track": {"f": 0, "p": 1, "x": 9e5, "y": 0}}\n' > tp/far.ndjson
printf 'generator = "files"\n[knobs]\nformat = "trajnetpp"\nscale = 100.0\n[values.a]\ntrain = ["tp/far.ndjson"]\ntest = ["tp/far.ndjson"]\n' > far.toml
row "8: TrajNet++ 9e5 at scale 100 (9e7 m)" $PY -m sim.generate --scenarios-dir "$W" --scenario far_a --out gen6
row "8: a 300-character SQLite name" $PY -m sim.bench --scenario crowd_noise_0.1..0.3 --quick --storage "sqlite:///$W/$($PY -c "print('s'*300)").db" --out bench3
C2I_DATA_ROOT="$($PY -c "print('/tmp/' + 'r'*5000)")" row "8: a 5,000-character \$C2I_DATA_ROOT" $PY -m sim.run --scenario sdd_trajnet_all --quick --methods cv
$PY -c "import json; d = json.load(open('$ROOT/sim/studies/benchmark/tunings/radius.json')); d['methods']['finetune']['settings']['data'] = {'agents': 3}; json.dump(d, open('tuned.json', 'w'))"
row "6: --tuned-from with a data setting" $PY -m sim.run --scenario crowd_radius_0.1 --quick --methods finetune --tuned-from tuned.json
row "7: pretrain_transfer --out a file" $PY "$ROOT/scripts/pretrain_transfer.py" --out /dev/null/x
row "7: ranking_transfer on no board" $PY "$ROOT/scripts/ranking_transfer.py" "$W" "$W"
row "2: a plugin named finetune (its pytest)" sh -c "cd '$ROOT' && $PY -m pytest -q -p no:cacheprovider tests/c2inet/test_methods.py -k named_like_a_built_in"
row "testbed without the sim extra" $PY -c "import runpy, sys; sys.modules['pymunk'] = None; sys.argv = ['-m']; runpy.run_module('sim.run', run_name='__main__')"
