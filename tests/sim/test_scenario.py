"""The scenario language: ranges, lists, joins, and one clear error for every bad input."""

import contextlib
import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from c2inet.errors import InputError
from sim.families import SCENARIOS_DIR
from sim.scenario import parse_scenario


def names(scenario: str, extra=None) -> list[str]:
    return [spec.name for spec in parse_scenario(scenario, extra)]


def test_range_takes_its_step_from_the_decimals_of_the_start():
    assert names("crowd_noise_0.1..0.6") == [f"crowd_noise_0.{k}" for k in range(1, 7)]
    assert [s.value for s in parse_scenario("crowd_noise_0.1..0.3")] == [0.1, 0.2, 0.3]


def test_explicit_step_list_and_join():
    assert names("crowd_density_0.05..0.15:0.05") == [
        "crowd_density_0.05",
        "crowd_density_0.10",
        "crowd_density_0.15",
    ]
    assert names("crowd_noise_0.1,0.3+crowd_radius_0.2") == [
        "crowd_noise_0.1",
        "crowd_noise_0.3",
        "crowd_radius_0.2",
    ]


def test_values_set_the_named_knob_over_the_family_defaults():
    (spec,) = parse_scenario("crowd_radius_0.3")
    knobs = spec.knobs
    assert knobs["radius"] == 0.3 and knobs["agents"] == 2 and knobs["layout"] == "circle_crossing"


def test_name_valued_family_resolves_files():
    specs = parse_scenario("eth_ucy_univ,eth")
    assert [s.name for s in specs] == ["eth_ucy_univ", "eth_ucy_eth"]
    univ = specs[0].knobs
    assert [Path(p).name for p in univ["train"]] == [
        "students001_train.txt",
        "students003_train.txt",
    ]
    assert [Path(p).name for p in univ["test"]] == ["students001_val.txt", "students003_val.txt"]


def test_numbered_names_take_ranges_and_lists():
    ranged = parse_scenario("orca_radius_0.2..0.4")
    assert [s.label for s in ranged] == ["0.2", "0.3", "0.4"]
    assert Path(ranged[1].knobs["train"][0]).name == "radius_0.3_train.txt"
    assert [s.label for s in parse_scenario("orca_radius_0.6,0.1")] == ["0.6", "0.1"]
    with pytest.raises(InputError, match="'0.7' is not a value of family 'orca_radius'"):
        parse_scenario("orca_radius_0.5..0.7")


def test_user_folder_adds_families(family_dir):
    assert names("tiny_noise_0.2", [family_dir]) == ["tiny_noise_0.2"]


def test_a_copy_of_a_built_in_family_replaces_it_with_a_notice(tmp_path, capsys):
    text = (SCENARIOS_DIR / "crowd_noise.toml").read_text().replace("agents = 10", "agents = 3")
    (tmp_path / "crowd_noise.toml").write_text(text)
    (spec,) = parse_scenario("crowd_noise_0.2", [tmp_path])
    assert spec.knobs["agents"] == 3 and spec.family.path.parent == tmp_path
    assert "replaces the built-in crowd_noise" in capsys.readouterr().err
    (other := tmp_path / "more").mkdir()
    (other / "crowd_noise.toml").write_text(text)
    with pytest.raises(InputError, match="already defined"):
        parse_scenario("crowd_noise_0.2", [tmp_path, other])


def test_data_overrides_change_knobs_and_split_sizes():
    (spec,) = parse_scenario("crowd_noise_0.2", None, {"agents": 4, "splits.train": 7})
    assert spec.knobs["agents"] == 4 and spec.family.splits.train == 7
    with pytest.raises(InputError, match="splits.train, .val or .test"):
        parse_scenario("crowd_noise_0.2", None, {"splits.trian": 7})


@pytest.mark.parametrize(
    ("scenario", "message"),
    [
        ("crowd_noise_0.6..0.1", "reversed"),
        ("crowd_noise_0.1..0.6:0", "must be positive"),
        ("crowd_noise_0.1..0.6:-0.1", "must be positive"),
        ("crowd_nois_0.1", "unknown family"),
        ("crowd_noise_abc", "not a number"),
        ("crowd_noise_0.1,,0.2", "empty value"),
        ("crowd_noise_-0.5", "out of range"),
        ("crowd_radius_0", "out of range"),
        ("crowd_density_5", "impossible density"),
        ("crowd_noise_0.1+", "empty part"),
        ("crowd_noise_0.1+crowd_noise_0.1", "appears twice"),
        ("crowd_radius_0.1,00.1", "are one value of family"),  # two spellings, one domain
        ("eth_ucy_paris", "not a value"),
        ("", "empty"),
        ("crowd_noise_0.001..10", "more than"),
        ("crowd_noise_0..1:0." + "0" * 25 + "1", "more than 64 domains"),  # a 26-digit count
        ("crowd_noise_0." + "0" * 300 + "1", "longer than 32 characters"),  # a file name
        ("crowd_noise_1e400", "not a number"),
    ],
)
def test_bad_scenarios_raise_one_clear_error(scenario, message):
    with pytest.raises(InputError, match=message) as error:
        parse_scenario(scenario)
    assert len(str(error.value)) < 300  # the input is quoted by a short prefix


def test_an_error_quotes_a_long_input_by_its_prefix():
    with pytest.raises(InputError, match=r"\.\.\. \(5007 characters\)"):
        parse_scenario("crowd_noise_" + "x" * 4995)


@pytest.mark.parametrize(
    ("scenario", "message"),
    [
        ("crowd_noise_" + "1" * 1990, "longer than 2000 characters"),
        ("crowd_noise_0.1.." + "1" * 1_200_000, "longer than 2000 characters"),
        ("crowd_noise_0.1," + "2" * 1000, "longer than 32 characters"),
        ("crowd_noise_0.1.." + "3" * 1900, "longer than 32 characters"),
        ("crowd_noise_0.1.." + "y" * 1900, "longer than 32 characters"),
    ],
)
def test_long_inputs_are_refused_before_parsing_with_a_short_message(scenario, message):
    """Issue 26, item 9: a 1.2-million-character range raised decimal.Overflow and a
    1,000-digit value took seconds; both are refused by their length, in one short line."""
    with pytest.raises(InputError, match=message) as error:
        parse_scenario(scenario)
    assert len(str(error.value)) < 300


@pytest.mark.parametrize(
    ("toml", "message"),
    [
        ('generator = "crowd"\nknob = "noise"\nknobz = 1\n', "unknown key 'knobz'"),
        ('generator = "crowd"\nknob = "noise"\n[knobs]\nradiuss = 0.2\n', "unknown key 'radiuss'"),
        ('generator = "crowd"\nknob = "noise"\n[splits]\ntrian = 3\n', "unknown key 'trian'"),
        ('generator = "crowd"\nknob = "nosie"\n', "not a knob"),
        ('generator = "warp"\nknob = "noise"\n', "generator 'warp': unknown"),
        ('generator = "crowd"\nknob = "noise"\n[knobs]\nagents = "many"\n', "must be an integer"),
        ('generator = "crowd"\nknob = "noise"\n[knobs]\nlayout = "maze"\n', "layout"),
        ("generator = [", "cannot read"),
        ("generator = 5\nknob = 'noise'\n", "'generator' must be the name"),
        ('generator = "crowd"\nknob = [1]\n', "not a knob"),
        ('generator = "crowd"\nknob = "noise"\nsplits = 3\n', "'splits' must be a table"),
        ('generator = "crowd"\nknob = "noise"\n[knobs]\nagents = 1e400\n', "must be an integer"),
        ('generator = "crowd"\nx = ' + "[" * 500 + "]" * 500, "nested too deeply"),
    ],
)
def test_bad_family_files_are_rejected(tmp_path, toml, message):
    (tmp_path / "bad.toml").write_text(toml)
    with pytest.raises(InputError, match=message):
        parse_scenario("bad_0.1", [tmp_path])


@settings(max_examples=300, deadline=None)
@given(st.text(alphabet="crowd_noiseradiusdensityeth_ucy0123456789.,:+-_ ", max_size=40))
def test_parser_returns_a_curriculum_or_raises_its_own_error(text):
    try:
        curriculum = parse_scenario(text)
    except InputError:
        return
    assert curriculum and all(spec.name for spec in curriculum)


@settings(max_examples=100, deadline=None)
@given(st.text(max_size=30))
def test_parser_survives_arbitrary_unicode(text):
    with contextlib.suppress(InputError):
        parse_scenario(text)


def test_a_family_file_must_be_a_regular_file(tmp_path):
    os.mkfifo(tmp_path / "piped.toml")  # reading it would block forever
    with pytest.raises(InputError, match="regular file"):
        parse_scenario("piped_0.1", [tmp_path])


@pytest.mark.parametrize(
    "value, message", [(1e400, "must be an integer"), (1.5, "must be an integer"), (-3, "range")]
)
def test_split_size_overrides_go_through_the_option_builder(value, message):
    """Found by benchmarks/fuzz.py: 1e400 crashed int(), and 1.5 was cut to 1."""
    with pytest.raises(InputError, match=message):
        parse_scenario("crowd_noise_0.1", overrides={"splits.train": value})


def test_a_training_window_stride_thins_training_windows_only(tmp_path):
    """``--set data.windows.stride=5`` (or a family's ``[windows] stride``): a recording's
    training windows start every fifth frame; validation and test keep every window."""
    from sim.experiment.curriculum import learner_tasks

    (every,) = learner_tasks("eth_ucy_eth", cache=tmp_path)
    (thinned,) = learner_tasks("eth_ucy_eth", data={"windows.stride": 5}, cache=tmp_path)
    assert len(thinned.train) < len(every.train) / 3
    assert len(thinned.test) == len(every.test)
    text = (SCENARIOS_DIR / "crowd_noise.toml").read_text()
    (tmp_path / "strided.toml").write_text(
        text.replace("[knobs]", "[windows]\nstride = 5\n\n[knobs]")
    )
    (spec,) = parse_scenario("strided_0.1", [tmp_path])
    assert spec.family.stride == 5


def test_a_training_share_keeps_the_first_training_windows_only(tmp_path):
    """``--set data.windows.share=0.1`` (or ``[windows] share``): the first tenth of the
    training windows, in the recording's order; validation and test keep every window; a share
    outside (0, 1] is one line."""
    from sim.experiment.curriculum import learner_tasks

    (every,) = learner_tasks("eth_ucy_eth", cache=tmp_path)
    (tenth,) = learner_tasks("eth_ucy_eth", data={"windows.share": 0.1}, cache=tmp_path)
    assert len(tenth.train) == -(-len(every.train) // 10)
    # the leading windows, exactly: the first of the full set
    head = every.train.subset(np.arange(len(tenth.train)))
    np.testing.assert_array_equal(tenth.train.positions, head.positions)
    assert len(tenth.test) == len(every.test)
    for share in (0, 1.5, True, "0.1"):
        with pytest.raises(InputError, match=r"windows.share=.*\(0, 1\]"):
            parse_scenario("eth_ucy_eth", overrides={"windows.share": share})
    text = (SCENARIOS_DIR / "crowd_noise.toml").read_text()
    (tmp_path / "tenth.toml").write_text(
        text.replace("[knobs]", "[windows]\nshare = 0.1\n\n[knobs]")
    )
    (spec,) = parse_scenario("tenth_0.1", [tmp_path])
    assert spec.family.share == 0.1


def test_windows_drop_lone_agents_when_asked_and_hold_out_a_validation_share(tmp_path):
    """``windows.min_agents = 2`` (sgan's windows, ``eth_ucy_loo``'s default) drops every window
    with one agent, in every split; ``1`` keeps them. ``windows.val_share`` holds the training
    windows' last share out as the validation split of a family without one, the windows that
    share frames with it dropped from training."""
    from sim.experiment.curriculum import learner_tasks

    (kept,) = learner_tasks("eth_ucy_loo_eth", data={"windows.min_agents": 1}, cache=tmp_path)
    (sgan,) = learner_tasks("eth_ucy_loo_eth", cache=tmp_path)  # the family's default: 2
    for split in ("train", "val", "test"):
        lone = (getattr(kept, split).agents_per_scene == 1).sum()
        assert lone > 0 and (getattr(sgan, split).agents_per_scene >= 2).all()
        assert len(getattr(sgan, split)) == len(getattr(kept, split)) - lone
    assert len(sgan.test) == 70  # sgan's ETH test set: 70 windows
    (whole,) = learner_tasks("eth_ucy_eth", cache=tmp_path)
    assert whole.val is None
    (held,) = learner_tasks("eth_ucy_eth", data={"windows.val_share": 0.2}, cache=tmp_path)
    assert len(held.val) == -(-len(whole.train) * 2 // 10)
    np.testing.assert_array_equal(held.val.positions, whole.train.subset(
        np.arange(len(whole.train) - len(held.val), len(whole.train))).positions)  # fmt: skip
    assert len(held.train) == len(whole.train) - len(held.val) - 19  # 19 overlap the first
    thin = {"windows.val_share": 0.2, "windows.val_stride": 5}  # a held-out window every 5th frame
    (sparse,) = learner_tasks("eth_ucy_eth", data=thin, cache=tmp_path)
    assert len(sparse.val) == -(-len(held.val) // 5) and len(sparse.train) == len(held.train)
    np.testing.assert_array_equal(sparse.val.positions, held.val.subset(
        np.arange(0, len(held.val), 5)).positions)  # fmt: skip
    for bad in ({"windows.min_agents": 0}, {"windows.val_share": 0.9}, {"windows.val_stride": 0}):
        with pytest.raises(InputError, match="windows"):
            parse_scenario("eth_ucy_eth", overrides=bad)


def test_a_familys_train_table_is_the_learners_default_under_set_and_flags():
    """``eth_ucy_loo``'s ``[train]`` table is what its runs train with; ``--set train.KEY`` and
    ``--epochs`` override it; families that disagree on it are one line; sizes below the
    family's are labelled reduced."""
    from sim.experiment import ExperimentConfig

    config = ExperimentConfig("eth_ucy_loo_zara1", ("finetune",))
    train = config.train_config()
    assert (config.epochs, train.k_train, train.select, train.schedule) == (60, 20, "val", "cosine")
    assert config.size == "full"
    lower = ExperimentConfig(
        "eth_ucy_loo_zara1", ("finetune",), epochs=5, settings={"train": {"select": "last"}}
    )
    assert lower.train_config().select == "last" and lower.epochs == 5
    assert lower.size == "reduced (5 of 60 epochs)"
    with pytest.raises(InputError, match="set different \\[train\\] defaults"):
        ExperimentConfig("eth_ucy_loo_zara1+crowd_noise_0.1", ("finetune",))
    half = ExperimentConfig("crowd_noise_0.1", ("cv",), settings={"data": {"splits.train": 150}})
    assert half.size == "reduced (train 150 of 300 scenes a task)"


def test_a_familys_model_table_sets_the_networks_defaults_under_set(tmp_path):
    """A family's ``[model]`` table (here a copy of ``eth_ucy_loo`` with a non-residual decoder)
    reaches the network a job builds; ``--set model.KEY`` overrides it; other families keep the
    learner's defaults; families that disagree on it alone are one line."""
    from sim.experiment import ExperimentConfig

    text = (SCENARIOS_DIR / "eth_ucy_loo.toml").read_text()
    plain = text.replace("[model]\n", "[model]\nresidual = false\n", 1)
    (tmp_path / "loo_plain.toml").write_text(plain)
    (tmp_path / "data").symlink_to(SCENARIOS_DIR / "data")  # the same recordings
    where = {"scenarios_dir": (tmp_path,)}
    config = ExperimentConfig("loo_plain_zara1", ("finetune",), **where)
    assert config.model_config().residual is False
    assert config.method("finetune").build_model().backbone.decoder.residual is False
    override = {"model": {"residual": True}}
    config = ExperimentConfig("loo_plain_zara1", ("cv",), settings=override, **where)
    assert config.model_config().residual is True
    shipped = ExperimentConfig("eth_ucy_loo_zara1", ("cv",)).model_config()
    assert shipped.residual is True and shipped.noise_per == "scene"  # the family's own table
    assert ExperimentConfig("crowd_noise_0.1", ("cv",)).model_config().noise_per == "agent"
    with pytest.raises(InputError, match="set different \\[model\\] defaults"):
        ExperimentConfig("eth_ucy_loo_zara1+loo_plain_zara1", ("cv",), **where)
    (tmp_path / "loo_bad.toml").write_text(plain.replace("residual = false", "resdual = false"))
    with pytest.raises(InputError, match="loo_bad.toml \\[model\\]: unknown key 'resdual'"):
        ExperimentConfig("loo_bad_zara1", ("cv",), **where)  # its file named, not --set
