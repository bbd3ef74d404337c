"""Shared fixtures: small family files in a temporary scenarios folder."""

from pathlib import Path

import pytest


@pytest.fixture
def family_dir(tmp_path: Path) -> Path:
    """A folder with a tiny crowd family, so tests generate in well under a second."""
    (tmp_path / "tiny_noise.toml").write_text(
        'generator = "crowd"\nknob = "noise"\n'
        '[knobs]\nlayout = "crossing"\nagents = 6\nlength = 10.0\nwidth = 3.0\n'
        "[splits]\ntrain = 6\nval = 2\ntest = 3\n"
    )
    return tmp_path
