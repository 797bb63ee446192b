"""``ftdrake results``: the results pages' files, the commands that write them, and one command
that regenerates them.

    ftdrake results                                  # list: page, commands, commit, time
    ftdrake results --regenerate [--only NAME ...]   # run them; copy the files into docs/
    ftdrake results --regenerate --quick             # tiny sizes into --work; docs/ untouched

The table is :data:`ftdrake.experiments.result_pages.RESULTS`; the pages render their figures
from the files at the docs build (``docs/hooks/result_files.py``).
"""

from __future__ import annotations

from . import args as a


def register(sub) -> None:
    """Adds ``results`` to an ``argparse`` subparsers object."""
    p = a.add_command(
        sub, "results", "list or regenerate the results pages' files",
        "Without --regenerate: each result, the page that cites it, the commands that write "
        "it, the commit its files were made at and how long a full run takes. A full "
        "regeneration takes hours on 2 cores.")
    p.add_argument("--regenerate", action="store_true",
                   help="run the commands and copy their files into docs/")
    p.add_argument("--only", action="append", metavar="NAME", default=[],
                   help="only this result (repeat for more; names as the list shows them)")
    p.add_argument("--quick", action="store_true",
                   help="run each command at a tiny size into --work and copy nothing into "
                        "docs/: checks the commands still write the files the pages cite")
    p.add_argument("--dry-run", action="store_true",
                   help="print the commands --regenerate would run, run nothing")
    p.add_argument("--work", type=a.output_folder, default="out/results", metavar="DIR",
                   help="folder the commands write into (one sub-folder each)")
    a.add_quiet(p, "no progress output (the commands run with --quiet too)")
    p.set_defaults(run=run_results)


def run_results(args) -> int:
    from ..experiments.result_pages import find, listing, regenerate

    with a.naming("--only", " ".join(args.only)):
        results = find(args.only)
    if not (args.regenerate or args.dry_run):
        print(listing(results, args.work))
        return 0
    written = regenerate(results, args.work, quick=args.quick, dry_run=args.dry_run,
                         quiet=args.quiet)
    if written:
        print("wrote " + ", ".join(written) + "; `python3 -m mkdocs build --strict` renders "
              "the pages from them")
    return 0
