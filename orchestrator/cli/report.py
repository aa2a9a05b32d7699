"""``jitterfmu report``: turn a campaign folder into an HTML or Markdown report."""

from __future__ import annotations

from pathlib import Path

COMMAND = "report"
HELP = "write the jitter report (budget chart, time histories, tables) of a campaign folder"


def add_arguments(parser) -> None:
    parser.add_argument("dir", type=Path, help="campaign output folder")
    parser.add_argument("--format", choices=("html", "md"), default="html",
                        help="self-contained HTML (default) or Markdown with PNG files")
    parser.add_argument("--out", type=Path, default=None, metavar="FILE",
                        help="report file (default: DIR/report.html or DIR/report.md)")


def run(args) -> int:
    # deferred: the parser imports every subcommand (orchestrator.cli)
    from ..progress import stage
    from ..report import write_report

    from ._options import shown

    stage(f"report {shown(args.dir)}: reading the results and drawing the figures")
    path = write_report(args.dir, args.format, args.out)
    print(f"report written to {path}")
    return 0
