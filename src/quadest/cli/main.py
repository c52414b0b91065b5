"""``quadest``: the command line. ``quadest --help`` lists the subcommands; each has ``--help``.

One module per group of commands (docs/developing.md): each command parses its options, calls
one library function and prints; the library does the work.
"""
from __future__ import annotations

import argparse
import sys

from quadest import __version__
from quadest.cli import compare, recordings, recovery, sim, sweep
from quadest.cli.common import CliError

GROUPS = (sim, recordings, compare, recovery, sweep)
ORDER = ("simulate", "info", "compare", "reproduce", "fit-aero", "recover", "calibrate", "estimate", "benchmark",
         "sweep", "tune", "demo")


def build_parser():
    p = argparse.ArgumentParser(
        prog="quadest",
        description="Quadcopter attitude and state estimation that keeps working when things go "
                    "wrong. Conventions: NED/FRD, q_nb = [w, x, y, z], SI units (docs/conventions.md).")
    p.add_argument("--version", action="version", version=f"quadest {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for group in GROUPS:
        group.add_parsers(sub)
    # the listing in --help keeps its order whatever module declares a command
    sub._choices_actions.sort(key=lambda a: ORDER.index(a.dest))
    return p


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return args.func(args)
    except BrokenPipeError:  # output piped into a command that stopped reading (head)
        return 0
    except (CliError, ValueError, OSError) as exc:
        print(f"quadest {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
