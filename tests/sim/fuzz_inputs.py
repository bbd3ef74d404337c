"""The fault suite's inputs: Hypothesis strategies for every way a user hands the project
something (scenarios, ``--set``, command lines, data files of every format, family and config
files, tuning stores, damages to a run folder). ``fuzzing.py`` feeds them to the project
(test machinery, not shipped)."""

from __future__ import annotations

import string

from hypothesis import strategies as st

FAMILIES = ["crowd_noise", "crowd_radius", "crowd_density", "highway_density", "eth_ucy", "nope"]

plain = st.one_of(
    st.decimals(0, 1, places=1).map(str),
    st.decimals(0, 1, places=2).map(str),
    st.sampled_from(["0.1", "0.2", "0.3", "0.6", "1", "2", "10"]),
)
numbers = st.one_of(
    plain,
    st.integers(-(10**6), 10**6).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.decimals(allow_nan=False, allow_infinity=False, places=3).map(str),
    st.sampled_from(["0.1", "0.6", "1e400", "-0", "1e-3000", "0." + "0" * 80 + "1", "nan"]),
    st.text(string.digits + ".-e", max_size=12),
)
values = st.one_of(
    plain,
    st.builds(lambda a, b: f"{a}..{b}", plain, plain),
    numbers,
    st.builds(lambda a, b: f"{a}..{b}", numbers, numbers),
    st.builds(lambda a, b, c: f"{a}..{b}:{c}", numbers, numbers, numbers),
    st.lists(numbers, min_size=1, max_size=4).map(",".join),
    st.sampled_from(["univ", "eth,hotel", "zara9", "", "0.1-0.6"]),
)
parts = st.builds(lambda f, v: f"{f}_{v}", st.sampled_from(FAMILIES), values)
scenarios = st.one_of(
    st.lists(
        st.builds(lambda f, v: f"{f}_{v}", st.sampled_from(["crowd_noise", "crowd_radius"]), plain),
        min_size=1,
        max_size=3,
    ).map("+".join),
    st.lists(parts, min_size=1, max_size=3).map("+".join),
    st.lists(parts, min_size=1, max_size=3).map(" + ".join),
    st.text(max_size=40),
)
option_keys = st.sampled_from(
    [
        "train.lr", "train.batch_scenes", "train.k_train", "train.epochs", "model.z_dim",
        "model.likelihood_std", "model.c_source", "model.backbone", "finetune.x", "ewc.strength",
        "ewc.gamma", "data.agents", "data.noise", "data.splits.train", "data.radius", "lr", "x.y",
    ]
)  # fmt: skip
option_values = st.one_of(numbers, st.sampled_from(["true", "false", "abc", "", "1.5", "-1"]))
settings = st.lists(
    st.one_of(
        st.builds(lambda k, v: f"{k}={v}", option_keys, option_values),
        st.text(max_size=20),
    ),
    max_size=3,
)
flags = st.sampled_from(
    [
        "--methods", "--epochs", "--seeds", "--k", "--seed", "--threads", "--jobs", "--workers",
        "--backend", "--logger", "--rerun", "--memory-budget", "--backbone", "--list",
    ]
)  # fmt: skip
flag_values = st.one_of(
    plain,
    st.builds(lambda a, b: f"{a}..{b}", plain, plain),
    numbers,
    st.sampled_from(
        ["finetune,cv", "all", "sgd", "ray", "csv", "spawnx", "connect=x", "methods", "knobs"]
    ),
)
argvs = st.builds(
    lambda scenario, pairs, sets: [
        *(["--scenario", scenario] if scenario is not None else []),
        *[x for pair in pairs for x in pair],
        *[x for s in sets for x in ("--set", s)],
    ],
    st.one_of(st.none(), scenarios),
    st.lists(st.tuples(flags, flag_values), max_size=3),
    settings,
)
token = st.one_of(numbers, st.text(string.printable, max_size=6))
rows = st.builds(
    lambda frame, agent, x, y: f"{frame * 10} {agent} {x} {y}",
    st.integers(0, 40),
    st.integers(1, 4),
    st.floats(-50, 50, allow_nan=False),
    st.floats(-50, 50, allow_nan=False),
)
data_files = st.one_of(
    st.lists(rows, max_size=60).map("\n".join),  # well-formed rows, frames in any order
    st.lists(st.one_of(rows, st.lists(token, max_size=6).map(" ".join)), max_size=12).map(
        "\n".join
    ),
    st.binary(max_size=64).map(lambda b: b.decode("latin-1")),
)
toml_values = st.one_of(
    plain,
    st.builds(lambda a, b: f"{a}..{b}", plain, plain),
    numbers,
    st.sampled_from(['"crowd"', '"files"', "true", "[1, 2]", "{a = 1}", '"x"', "[[[]]]"]),
)
knob_lines = st.lists(
    st.tuples(
        st.sampled_from(["agents", "radius", "noise", "frames", "layout", "speed", "density"]),
        st.one_of(plain, st.sampled_from(["2", "6", "20", '"corridor"', '"x"']), numbers),
    ),
    max_size=3,
    unique_by=lambda kv: kv[0],
)
family_files = st.one_of(
    st.builds(  # a crowd family, its knobs and splits drawn
        lambda knob, pairs, splits: (
            f'generator = "crowd"\nknob = "{knob}"\n[knobs]\n'
            + "".join(f"{k} = {v}\n" for k, v in pairs)
            + f"[splits]\ntrain = {splits[0]}\nval = {splits[1]}\ntest = {splits[2]}\n"
        ),
        st.sampled_from(["noise", "radius", "agents", "speed", "x"]),
        knob_lines,
        st.tuples(*[st.integers(-1, 12)] * 3),
    ),
    st.builds(
        lambda gen, knob, pairs, table: (
            f"generator = {gen}\nknob = {knob}\n"
            + "".join(f"{k} = {v}\n" for k, v in pairs)
            + f"[{table}]\n"
            + "".join(f"{k} = {v}\n" for k, v in pairs)
        ),
        toml_values,
        toml_values,
        st.lists(
            st.tuples(
                st.sampled_from(["agents", "radius", "noise", "train", "test", "frames", "zz"]),
                toml_values,
            ),
            max_size=3,
        ),
        st.sampled_from(["knobs", "splits", "values.a", "values", "other"]),
    ),
    st.text(max_size=60),
    st.integers(1, 400).map(lambda n: 'generator = "crowd"\nx = ' + "[" * n + "]" * n),
)


sdd_rows = st.builds(  # raw SDD annotations: track, box, frame, lost, occluded, generated, label
    lambda track, box, frame, flags, label: (
        f"{track} {box[0]} {box[1]} {box[0] + box[2]} {box[1] + box[3]} {frame} "
        f'{flags[0]} {flags[1]} {flags[2]} "{label}"'
    ),
    st.integers(0, 3),
    st.tuples(*[st.integers(0, 2000)] * 4),
    st.integers(0, 60).map(lambda f: f * 12),
    st.tuples(*[st.integers(0, 1)] * 3),
    st.sampled_from(["Pedestrian", "Biker", "Car", "x"]),
)
sdd_files = st.one_of(
    st.lists(sdd_rows, max_size=60).map("\n".join),
    st.lists(st.one_of(sdd_rows, st.lists(token, max_size=10).map(" ".join)), max_size=12).map(
        "\n".join
    ),
    st.binary(max_size=64).map(lambda b: b.decode("latin-1")),
)
json_numbers = st.one_of(
    st.integers(-5, 60),
    st.floats(-50, 50, allow_nan=False),
    st.sampled_from(["Infinity", "NaN", "1e309", "1" * 320, "0.5", '"3"', "null", "1e8"]),
)
trajnet_lines = st.one_of(
    st.builds(
        lambda i, p, s, e: f'{{"scene": {{"id": {i}, "p": {p}, "s": {s}, "e": {e}, "fps": 2.5}}}}',
        json_numbers,
        json_numbers,
        json_numbers,
        json_numbers,
    ),
    st.builds(
        lambda f, p, x, y: f'{{"track": {{"f": {f}, "p": {p}, "x": {x}, "y": {y}}}}}',
        json_numbers,
        json_numbers,
        json_numbers,
        json_numbers,
    ),
    st.text(max_size=20),
)
trajnet_scene = st.builds(  # a well-formed file: one scene, its agents on every frame
    lambda agents, frames, dx: "\n".join(
        [f'{{"scene": {{"id": 0, "p": 1, "s": 0, "e": {frames - 1}, "fps": 2.5}}}}']
        + [
            f'{{"track": {{"f": {f}, "p": {a}, "x": {a + f * dx}, "y": {a}}}}}'
            for f in range(frames)
            for a in range(1, agents + 1)
        ]
    ),
    st.integers(1, 4),
    st.integers(1, 30),
    st.floats(-1, 1, allow_nan=False),
)
trajnet_files = st.one_of(
    trajnet_scene,
    st.builds(lambda good, bad: good + "\n" + bad, trajnet_scene, trajnet_lines),
    st.lists(trajnet_lines, max_size=40).map("\n".join),
    st.binary(max_size=64).map(lambda b: b.decode("latin-1")),
)
config_keys = st.sampled_from(
    [
        "scenario", "methods", "seed", "seeds", "epochs", "k", "backbone", "quick", "record",
        "jobs", "threads", "workers", "cache", "loggers", "device", "memory_budget", "nope",
    ]
)  # fmt: skip
config_values = st.one_of(
    toml_values,
    st.sampled_from(['"crowd_noise_0.1,0.2"', '"finetune,cv"', '["finetune"]', "2", '"2"', "0"]),
)
tuning_storages = st.one_of(
    st.binary(max_size=200),
    st.just(b"SQLite format 3\x00"),  # a header and nothing behind it
    st.binary(max_size=100).map(lambda b: b"SQLite format 3\x00" + b),
)
config_files = st.one_of(
    st.builds(  # TOML: options, then --set tables
        lambda pairs, sets: (
            "".join(f"{k} = {v}\n" for k, v in pairs)
            + "".join(f"[settings.{scope}]\n{key} = {value}\n" for scope, key, value in sets)
        ),
        st.lists(st.tuples(config_keys, config_values), max_size=5, unique_by=lambda kv: kv[0]),
        st.lists(
            st.tuples(
                st.sampled_from(["train", "model", "data", "finetune", "x"]),
                st.sampled_from(["lr", "batch_scenes", "z_dim", "splits", "agents", "y"]),
                config_values,
            ),
            max_size=2,
            unique_by=lambda t: t[0],
        ),
    ),
    st.builds(  # a run's config.json, its tables drawn
        lambda experiment, execution: f'{{"experiment": {experiment}, "execution": {execution}}}',
        st.sampled_from(['{"scenario": "crowd_noise_0.1"}', "[]", "{}", "1", '{"seeds": "x"}']),
        st.sampled_from(['{"jobs": 2}', '{"cache": "/"}', "null", "[]", '{"loggers": ["csv"]}']),
    ).map(lambda text: "JSON:" + text),
    st.text(max_size=60),
)


DAMAGES = ("truncated", "emptied", "garbage", "a folder", "another run's", "deleted")
run_damages = st.tuples(st.integers(0, 10**6), st.sampled_from(DAMAGES), st.booleans())
