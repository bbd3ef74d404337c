"""``python -m sim.generate``: generate a curriculum's domains and write them with a summary.

Writes one file (or folder) per domain and ``summary.json``, the machine-readable contract:
scenario, seed, and per domain its knobs, split sizes, realised statistics and content hash.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from c2inet.errors import InputError
from c2inet.files import file_digest, writable_folder, write_text_atomic
from c2inet.lazy import lazy_module
from sim import io
from sim.cli import add_workers, parse, parser
from sim.data import SPLITS, Domain
from sim.progress import progress_bar
from sim.scenario import parse_scenario
from viz.cli import guarded

# loaded on first use: a command that stops at bad input or answers --help does not pay for it
building = lazy_module("sim.domains")  # the simulators load once there is work
engine_config = lazy_module("sim.experiment.config")

STAT_COLUMNS = ("mean_speed", "min_separation", "heading_change", "density", "overlaps")


def _stat(value) -> str:
    """A statistic as printed: 3 decimals, or '-' where a domain has none (real-data overlaps)."""
    return "-" if value is None else f"{value:.3f}" if isinstance(value, float) else str(value)


def format_table(domains: list[Domain], knob_names: list[str]) -> str:
    """A fixed-width table of domains, their varied knobs and realised statistics."""
    header = ["domain", *knob_names, "train/val/test", *STAT_COLUMNS]
    rows = []
    for d in domains:
        knobs = [str(d.knobs.get(k, "")) for k in knob_names]
        sizes = "/".join(str(len(d.scenes[s])) for s in SPLITS)
        stats = [_stat(d.stats.get(c)) for c in STAT_COLUMNS]
        rows.append([d.name, *knobs, sizes, *stats])
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    return "\n".join(
        "  ".join(str(c).rjust(w) for c, w in zip(r, widths, strict=True)) for r in [header, *rows]
    )


WRITERS = ("ethucy", "npz", "parquet")  # the formats, each by sim.io's write_FORMAT


def write_domain(format: str, domain: Domain, out: Path) -> None:
    """``domain`` in ``format`` where :data:`WRITTEN` says (pyarrow loads only to write)."""
    getattr(io, f"write_{format}")(domain, WRITTEN[format](out, domain.name))


WRITTEN = {  # what each writer leaves for a domain: a file or a folder of its own
    "parquet": lambda out, name: out / f"{name}.parquet",
    "ethucy": lambda out, name: out / name,
    "npz": lambda out, name: out / name,
}
MARKER = ".c2i-generated.json"  # what a generate wrote here: each file's path and SHA-256


def clear_output(out: Path, overwrite: bool) -> None:
    """Never overwrite silently: an empty or new ``out`` is used as it is; with ``overwrite``, a
    folder an earlier generate wrote loses exactly the files its marker records, each only if
    its bytes are still the ones written (then the folders they leave empty); anything else is
    refused. No file a user wrote, however named, is removed on the word of a file."""
    if not out.is_dir() or not any(out.iterdir()):
        return
    if not overwrite:
        raise InputError(f"--out {out}: not empty; add --overwrite to replace an earlier generate")
    try:
        written = json.loads((out / MARKER).read_text())["files"]
        if not isinstance(written, dict):
            raise TypeError("not a table of files")
    except (OSError, ValueError, KeyError, TypeError):
        raise InputError(
            f"--overwrite: {out} holds no output of sim.generate (no readable {MARKER}), so "
            "nothing is removed; choose another --out"
        ) from None
    root = out.resolve()
    folders = set()
    for name, digest in written.items():
        path = out / str(name)  # a link is never followed: only a plain file of ours goes
        inside = path.resolve().is_relative_to(root) and path.resolve() != root
        if inside and not path.is_symlink() and path.is_file() and file_digest(path) == digest:
            path.unlink()
            parents = (p.resolve() for p in path.parents)
            folders.update(p for p in parents if p.is_relative_to(root) and p != root)
    for folder in sorted(folders, key=lambda p: len(p.parts), reverse=True):
        if folder.is_dir() and not any(folder.iterdir()):
            folder.rmdir()
    (out / MARKER).unlink()


def record_written(out: Path, paths: list[Path], written: dict[str, str]) -> None:
    """Add ``paths`` (files, or folders of files) to the marker of what this generate wrote."""
    for path in paths:
        for file in sorted(path.rglob("*")) if path.is_dir() else [path]:
            if file.is_file():
                written[file.relative_to(out).as_posix()] = file_digest(file)
    write_text_atomic(out / MARKER, json.dumps({"files": written}, indent=1) + "\n")


@guarded
def main(argv: list[str] | None = None) -> int:
    examples = (
        "  python -m sim.generate --scenario crowd_radius_0.1..0.6 --out out/radius\n"
        "  python -m sim.generate --scenario eth_ucy_eth,hotel --out out/eth --format npz"
    )
    p = parser("sim.generate", __doc__.splitlines()[0], examples)
    p.add_argument("--out", type=Path, help="output folder (required)")
    p.add_argument("--format", choices=WRITERS, default="parquet")
    p.add_argument(
        "--set", action="append", default=[], metavar="data.KNOB=VALUE", help="override a knob"
    )
    p.add_argument(
        "--overwrite", action="store_true", help="replace what an earlier generate wrote in --out"
    )
    add_workers(p)
    args = parse(p, sys.argv[1:] if argv is None else argv)
    if args is None:
        return 0
    if args.out is None:
        p.error("the following arguments are required: --out")
    settings = engine_config.parse_settings(args.set)
    for scope in set(settings) - {"data"}:
        raise InputError(f"--set {scope}.*: generate takes only data.KNOB=VALUE")
    # a --config file's [settings.data] as sim.run reads it, under the flags; its learner's
    # scopes are not generate's, and said so
    data = {**args.config_settings.get("data", {}), **settings.get("data", {})}
    others = sorted(set(args.config_settings) - {"data"})
    if others:
        print(f"note: --config: generate takes its data settings, not {', '.join(others)}",
              file=sys.stderr)  # fmt: skip
    curriculum = parse_scenario(args.scenario, args.scenarios_dir, data)
    clear_output(args.out, args.overwrite)
    writable_folder(args.out, "--out")
    domains, written = [], {}
    for spec in progress_bar(curriculum, desc="domains", unit="domain"):
        domain = building.build_domain(
            spec, args.seed, workers=args.workers, memory_budget=args.memory_budget
        )
        write_domain(args.format, domain, args.out)
        record_written(args.out, [WRITTEN[args.format](args.out, domain.name)], written)
        domains.append(domain)
    summary = {
        "scenario": args.scenario,
        "seed": args.seed,
        "format": args.format,
        "domains": [d.summary() for d in domains],
    }
    write_text_atomic(args.out / "summary.json", json.dumps(summary, indent=2) + "\n")
    record_written(args.out, [args.out / "summary.json"], written)
    knob_names = sorted({s.family.knob for s in curriculum if s.family.knob})
    print(format_table(domains, knob_names))
    print(f"wrote {len(domains)} domains to {args.out}: summary.json lists them")
    return 0


if __name__ == "__main__":
    sys.exit(main())
