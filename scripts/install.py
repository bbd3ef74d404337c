"""Install the project into the running interpreter's virtual environment, as `make` does.

uv installs the same packages as pip (the same requirements, constraints and indexes) in about a
quarter of the time, which is most of a fresh clone's `make test` setup. uv does not read pip's
configuration, so this machine's (`pip config list`: a constraints file, local wheel folders,
extra indexes, a certificate bundle) is handed to it as the UV_* variables that mean the same,
with pip's way of choosing among indexes (the best version in any of them). Where uv cannot be
installed or fails, pip installs instead: the result is the same, only slower.

    python scripts/install.py -e '.[test]'
"""

from __future__ import annotations

import os
import subprocess
import sys

# pip's configuration key -> uv's variable of the same meaning
PIP_TO_UV = {
    "constraint": "UV_CONSTRAINT",
    "find-links": "UV_FIND_LINKS",
    "index-url": "UV_DEFAULT_INDEX",
    "extra-index-url": "UV_EXTRA_INDEX_URL",
    "cert": "SSL_CERT_FILE",
}


def pip(*args: str, **kwargs) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "pip", "--disable-pip-version-check", *args]
    return subprocess.run(command, text=True, **kwargs)


def uv_environment() -> dict[str, str]:
    """The environment with pip's configuration (files and PIP_* variables) as UV_* variables;
    a value set in several places takes the last, as pip does (its variables last)."""
    listed = pip("config", "list", capture_output=True).stdout.splitlines()
    listed.sort(key=lambda line: line.startswith(":env:"))  # pip's variables override its files
    env = dict(os.environ, UV_INDEX_STRATEGY="unsafe-best-match", UV_PYTHON=sys.executable)
    for line in listed:  # global.find-links='/opt/wheels'  or  :env:.find-links='/opt/wheels'
        key, _, value = line.partition("=")
        name, value = key.rpartition(".")[2], value.strip("'\"")
        if name in PIP_TO_UV:  # pip separates several values by spaces; uv's find-links by commas
            env[PIP_TO_UV[name]] = ",".join(value.split()) if name == "find-links" else value
    return env


def main(args: list[str]) -> int:
    if pip("install", "--quiet", "uv").returncode == 0:
        uv = [sys.executable, "-m", "uv", "pip", "install", "--quiet", *args]
        if subprocess.run(uv, env=uv_environment()).returncode == 0:
            return 0
        print("install: uv failed; installing with pip", file=sys.stderr)
    return pip("install", "--quiet", "--no-compile", *args).returncode


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
