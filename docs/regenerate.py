"""Write the docs' generated figures: ``python docs/regenerate.py [--measure NAME ...] [--check] [--list]``.

Without options: every page's generated blocks are written again from the code and the stored measurements
(seconds). ``--measure NAME`` (repeatable; ``--measure all`` for every deterministic one, ``--measure timing``
for the machine-dependent ones) runs measurements first and stores their results in docs/figures/data/.
``--check`` writes nothing and exits 5 when a page differs from what the code prints now (CI runs it);
``--page FILE`` limits the writing or checking to that page;
``--list`` names the measurements and how long each takes. Run from anywhere.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

try:
    from cogapp import Cog
except ImportError:  # the test extra brings it
    sys.exit("docs/regenerate.py needs cogapp, which comes with the test extra: pip install \".[test]\"")

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(DOCS))

from figures.common import isolated_station, load_all, measure  # noqa: E402  (needs docs/ on the path)


def pages() -> list[Path]:
    """Every page that may hold generated figures."""
    return [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]


def run_cog(*, check: bool, only: list[Path] | None = None) -> int:
    """Run cog over the pages (or ``only`` these): rewrite them, or (``check``) report the ones that would change."""
    options = ["--check", "--diff", "--check-fail-msg=run `python docs/regenerate.py`"] if check else ["-r"]
    with isolated_station():  # what this machine's station holds must not change a figure
        return Cog().main(["cog", *options, "-I", str(DOCS), *map(str, only or pages())])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--measure", action="append", default=[], metavar="NAME",
                        help="measure again first: a name, 'all' (the deterministic ones) or 'timing'")
    parser.add_argument("--check", action="store_true", help="write nothing; exit 5 if a page is out of date")
    parser.add_argument("--list", action="store_true", help="list the measurements")
    parser.add_argument("--page", action="append", type=Path, default=[], metavar="FILE",
                        help="only this page (repeatable; default: README.md and every docs/*.md)")
    args = parser.parse_args(argv)
    registry = load_all()
    if args.list:
        for entry in sorted(registry.values(), key=lambda e: e.name):
            kind = "timing" if entry.timing else "deterministic"
            print(f"{entry.name:40s} {kind:13s} about {entry.minutes:g} min")
        return 0
    names: list[str] = []
    for name in args.measure:
        if name == "all":
            names += [n for n, e in registry.items() if not e.timing]
        elif name == "timing":
            names += [n for n, e in registry.items() if e.timing]
        elif name in registry:
            names.append(name)
        else:
            parser.error(f"no measurement is named {name!r}; `--list` names them")
    for name in dict.fromkeys(names):
        print(f"measuring {name} (about {registry[name].minutes:g} min) ...", flush=True)
        try:
            print(f"  wrote {measure(name)}", flush=True)
        except (RuntimeError, OSError) as exc:  # a command the measurement ran failed: its figures are not figures
            print(f"measurement {name} failed, nothing stored: {exc}", file=sys.stderr)
            return 1
    for page in args.page:
        if not page.is_file():
            parser.error(f"--page {page}: no such file")
    return run_cog(check=args.check, only=[page.resolve() for page in args.page])


if __name__ == "__main__":
    try:
        sys.exit(main())
    except BrokenPipeError:  # the reader (head, a pager) closed the pipe: nothing more to say
        sys.stderr.close()
        sys.exit(0)
