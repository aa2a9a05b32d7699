"""``jitterfmu keys``: every key of the files a user writes, from the parsers' schema."""

from __future__ import annotations

COMMAND = "keys"
HELP = ("list every key of scenario, campaign, uncertainty and sweep files: type, unit, "
        "default, allowed values, an example")


def add_arguments(parser) -> None:
    """Declare the options of ``jitterfmu keys``."""
    from orchestrator.schema import FILES

    parser.add_argument("kind", nargs="*", default=[], metavar="KIND",
                        help=f"file kinds: {', '.join(FILES)} (default: all)")
    parser.add_argument("--markdown", action="store_true",
                        help="Markdown, as docs/reference.md (which is this for every "
                             "kind)")


def run(args) -> int:
    """Print the reference; return 0."""
    import difflib

    from orchestrator.schema import FILES, markdown, text

    for kind in args.kind:
        if kind not in FILES:
            close = difflib.get_close_matches(kind, list(FILES), 1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ValueError(f"no file kind {kind!r}{hint}; expected one of "
                             f"{', '.join(FILES)}")
    kinds = args.kind or None
    print(markdown(kinds) if args.markdown else text(kinds), end="")
    return 0
