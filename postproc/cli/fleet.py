"""``postproc fleet``: train, validate and report every robot of a fleet file on a task engine."""
from __future__ import annotations

import sys
from pathlib import Path

FORMATS = ("md", "csv", "html")

EXAMPLES = """\
Exit codes: 0 every robot done, 1 a robot failed (its row says why; the others finish),
2 bad fleet file (P610 at its line).

Examples:
  postproc fleet fleet.toml -o fleet-out                      # local cluster, all cores
  postproc fleet fleet.toml -o fleet-out --format html --force
  postproc fleet fleet.toml -o fleet-out --scheduler tcp://10.0.0.5:8786
"""


def add_parser(sub, common, formatter) -> None:
    p = sub.add_parser(
        "fleet",
        parents=[common],
        formatter_class=formatter,
        help="train and report a fleet of robots (one task per robot; Dask)",
        description="Run `postproc train` and `postproc report` for every [[robot]] of a fleet file, in parallel "
        "(local Dask cluster by default), and write the fleet table. Robots whose inputs did not change are skipped.",
        epilog=EXAMPLES,
    )
    p.add_argument("fleet", metavar="FLEET.toml", help="fleet file ([defaults], [[robot]] name/data/robot/previous)")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="folder of the outputs (one folder per robot)")
    p.add_argument("--scheduler", "--address", dest="address", metavar="ADDRESS",
                   help="Dask scheduler of a real cluster (default: a local one)")
    p.add_argument("--workers", type=int, metavar="N", help="robots trained at a time on the local cluster (default: cores; a third as many report "
                   "workers besides)")
    p.add_argument("--format", choices=FORMATS, default="md", help="fleet table format (default md)")
    p.add_argument("--force", action="store_true", help="rerun robots whose inputs did not change")
    p.set_defaults(run=run)


def run(args) -> int:
    from ..fleet.cluster import run_fleet
    from ..fleet.jobs import load_fleet
    from ..fleet.table import fleet_table

    jobs = load_fleet(args.fleet)
    results = run_fleet(jobs, args.output, address=args.address, workers=args.workers, force=args.force)
    table = fleet_table(results, args.format)
    (Path(args.output) / f"fleet.{args.format}").write_text(table, encoding="utf-8")
    sys.stdout.write(table)
    return 0 if all(r["ok"] for r in results) else 1
