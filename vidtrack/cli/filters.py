"""``vidtrack filters [NAME]``: the registered trackers, or one tracker's options.

Without a name: one ``name  description`` line per tracker, sorted by name.
With one: its description, then every option of its configuration
(:func:`vidtrack.config.describe`) as ``key  default  type  doc``, dotted keys
for the fields of a group; any of them may be set with ``--set KEY=VALUE``.
"""

from __future__ import annotations

from typing import Sequence

from .common import EXIT_OK, OneLineParser


def format_options(rows: Sequence[tuple[str, str, str, str]]) -> list[str]:
    """``(key, default, type, doc)`` rows as aligned ``key  default  type  doc`` lines, with a header."""
    header = ("option", "default", "type", "doc")
    widths = [max(len(row[i]) for row in (header, *rows)) for i in range(3)]
    return [f"  {key:<{widths[0]}}  {default:<{widths[1]}}  {kind:<{widths[2]}}  {doc}".rstrip()
            for key, default, kind, doc in (header, *rows)]


def main(argv: Sequence[str]) -> int:
    """``vidtrack filters [NAME]``: exit 0 (2 for an unknown name)."""
    from ..api import tracker_config
    from ..config import describe
    from ..recipes import registry

    parser = OneLineParser(prog="vidtrack filters",
                           description="List every registered tracker, or one tracker's options with their "
                                       "defaults, types and docs.")
    parser.add_argument("name", nargs="?", metavar="NAME", help="show this tracker's options")
    args = parser.parse_args(argv)
    recipes = registry()
    if args.name is None:
        width = max(len(name) for name in recipes)
        for name in sorted(recipes):
            print(f"{name:<{width}}  {recipes[name].description}")
        return EXIT_OK
    config = tracker_config(args.name)   # an unknown name: the usual one line
    print(f"{args.name}: {recipes[args.name].description}")
    if config is None:
        print("options: none")
        return EXIT_OK
    print(f"options (--set KEY=VALUE, --config FILE.toml; vidtrack.create({args.name!r}, settings={{KEY: VALUE}})):")
    print("\n".join(format_options(describe(config))))
    return EXIT_OK
