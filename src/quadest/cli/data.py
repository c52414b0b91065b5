"""``quadest data``: the public datasets quadest reads, listed, fetched and found."""

from __future__ import annotations

from quadest.cli.common import say


def _size(n: int) -> str:
    return f"{n / 1e6:.1f} MB" if n else "-"


def cmd_data_list(args):
    from quadest.readers.catalog import DATASETS, cache_dir, is_fetched

    root = cache_dir(args.dir)
    say(f"datasets quadest reads (cache: {root}; QUADEST_DATA or --dir to move it)")
    for d in DATASETS.values():
        state = (
            ("fetched" if is_fetched(d, args.dir) else "quadest data fetch " + d.name)
            if d.fetchable
            else "not fetched by quadest: see below"
        )
        say(
            f"\n{d.name}: {d.title}\n  {d.publication}\n  terms: {d.terms}; size {_size(d.size)}; {state}\n"
            f"  contents: {d.contents}\n  source: {d.source}"
        )
        for n in d.notes:
            say(f"  note: {n}")
        if not d.fetchable:
            say(f"  how to get it: {d.instructions}")
    return 0


def cmd_data_fetch(args):
    from quadest.readers.catalog import cache_dir, dataset, fetch

    d = dataset(args.name)
    trials = [t for t in args.trials.split(",")] if args.trials else None
    say(f"fetching {d.name} ({d.title}) into {cache_dir(args.dir) / d.name}; each file checked against its SHA-256")
    folder = fetch(d.name, root=args.dir, trials=trials, progress=True)
    say(f"{d.name}: ready")
    say(str(folder))
    return 0


def cmd_data_path(args):
    from quadest.readers.catalog import cache_dir, dataset, is_present, not_present_reason

    d = dataset(args.name)
    folder = cache_dir(args.dir) / d.name
    if not is_present(d, args.dir):
        say(f"{folder} (not there yet: {not_present_reason(d, args.dir)})")
        return 1
    say(str(folder))
    return 0


def add_parsers(sub):
    p = sub.add_parser(
        "data",
        help="the public datasets the benchmarks use: list, fetch, path",
        description="The public datasets quadest reads (BROAD, Blackbird, DIDO, RepoIMU, PX4 and "
        "ArduPilot logs): where each comes from and on what terms, downloaded from "
        "its authors' repository into a cache (~/.cache/quadest/data, or "
        "QUADEST_DATA), each file checked against its SHA-256, an interrupted "
        "download resumed. Commands that take --data accept a dataset's name (or all).",
    )
    dsub = p.add_subparsers(dest="data_command", metavar="ACTION", required=True)
    lst = dsub.add_parser("list", help="each dataset: publication, terms, size, source, and whether it is fetched")
    lst.set_defaults(func=cmd_data_list)
    f = dsub.add_parser("fetch", help="download a dataset into the cache and print its folder")
    f.add_argument("name", help="the dataset (quadest data list)")
    f.add_argument(
        "--trials",
        metavar="A,B",
        help="only these trials (names or prefixes such as 02,07), for a dataset of trials (broad)",
    )
    f.set_defaults(func=cmd_data_fetch)
    pa = dsub.add_parser("path", help="print a dataset's folder (exit 1 when it is not there)")
    pa.add_argument("name")
    pa.set_defaults(func=cmd_data_path)
    for s in (lst, f, pa):
        s.add_argument(
            "--dir",
            metavar="DIR",
            default=None,
            help="the cache folder (default: QUADEST_DATA, else ~/.cache/quadest/data)",
        )


__all__ = ["add_parsers", "cmd_data_fetch", "cmd_data_list", "cmd_data_path"]
