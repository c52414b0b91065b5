"""``quadest``: the command line. ``quadest --help`` lists the subcommands; each has ``--help``.

One module per group of commands (docs/developing.md): each command parses its options, calls
one library function and prints; the library does the work.
"""

from __future__ import annotations

import os
import signal
import sys
import threading

INTERRUPTED = 130
"""The exit code after Ctrl-C (128 + SIGINT), whenever it comes."""


def interrupted() -> None:
    """Ctrl-C: one line, exit code 130, no traceback."""
    try:
        sys.stderr.write("quadest: interrupted\n")
        sys.stderr.flush()
    finally:
        os._exit(INTERRUPTED)


def _interrupt_in_a_callback(unraisable) -> None:
    """A Ctrl-C inside a C library's callback into Python (llvmlite's, as numba loads or saves
    compiled code) cannot be raised there: Python would print it as "Exception ignored ..." with
    a traceback and go on without it. It ends the program as any Ctrl-C does; anything else is
    Python's own report."""
    if issubclass(unraisable.exc_type, KeyboardInterrupt):
        interrupted()
    sys.__unraisablehook__(unraisable)


def _while_loading(signum, frame) -> None:
    """Ctrl-C while the command line loads (numpy, scipy, numba, ...: about a second): a C
    extension's initialisation turns the KeyboardInterrupt into an ImportError, which ends in a
    traceback or, in a library's optional import, is swallowed and the Ctrl-C lost; nothing is
    written yet, so the process ends here."""
    interrupted()


def _ctrl_c_is_pythons() -> bool:
    """Ctrl-C is Python's own (not ignored, not replaced) and this is the main thread."""
    return threading.current_thread() is threading.main_thread() and (
        signal.getsignal(signal.SIGINT) is signal.default_int_handler
    )


_LOADING = _ctrl_c_is_pythons()
if _LOADING:
    signal.signal(signal.SIGINT, _while_loading)
try:  # Ctrl-C while the command line loads ends in one line too
    import argparse
    import importlib
    import traceback
    import warnings
    from pathlib import Path

    from quadest.cli import benchmark, compare, data, fly, recordings, recovery, report, reproduce, sim, sweep, vehicle
    from quadest.cli.common import OUTPUT_NAMES, CliError, add_verbosity, data_on_stdout, set_verbosity
    from quadest.errors import UsageError
    from quadest.extras import MissingExtra, need
except KeyboardInterrupt:
    interrupted()
finally:
    if _LOADING:
        signal.signal(signal.SIGINT, signal.default_int_handler)

LIBRARIES = ("numpy", "scipy.linalg", "scipy.signal", "scipy.optimize", "scipy.spatial", "numba")
"""The compiled libraries a command loads when it runs (the command line's own modules load none)."""

_program = False  # main() runs as the program (the console script), not called from Python


def load_libraries() -> None:
    """Load the compiled libraries before a command runs, a Ctrl-C meanwhile ending the program
    at once as while the command line loads (:func:`_while_loading`): nothing is written yet."""
    ends_at_once = _program and _ctrl_c_is_pythons()
    if ends_at_once:
        signal.signal(signal.SIGINT, _while_loading)
    try:
        for name in LIBRARIES:
            importlib.import_module(name)
    finally:
        if ends_at_once:
            signal.signal(signal.SIGINT, signal.default_int_handler)


GROUPS = (sim, fly, recordings, vehicle, report, compare, reproduce, benchmark, recovery, sweep, data)
ORDER = (
    "simulate",
    "fly",
    "info",
    "identify",
    "diagnose",
    "report",
    "compare",
    "reproduce",
    "fit-aero",
    "recover",
    "calibrate",
    "estimate",
    "benchmark",
    "sweep",
    "tune",
    "campaign",
    "data",
    "demo",
)


class Version(argparse.Action):
    """``--version``: the installed version, read only when asked (importlib.metadata)."""

    def __call__(self, parser, namespace, values, option_string=None):
        import quadest

        print(f"quadest {quadest.__version__}")
        parser.exit()


def build_parser():
    p = argparse.ArgumentParser(
        prog="quadest",
        description="Quadcopter attitude and state estimation that keeps working when things go "
        "wrong. Conventions: NED/FRD, q_nb = [w, x, y, z], SI units (docs/conventions.md).",
    )
    p.add_argument("--version", action=Version, nargs=0, help="show program's version number and exit")
    p.add_argument(
        "--debug", action="store_true", help="on an error, show the full traceback (also accepted after the command)"
    )
    add_verbosity(p, top=True)
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for group in GROUPS:
        group.add_parsers(sub)
    for command in sub.choices.values():
        add_force(command)
        add_verbosity(command)
    # the listing in --help keeps its order whatever module declares a command
    sub._choices_actions.sort(key=lambda a: ORDER.index(a.dest))
    return p


# options that name files a command reads, and the options of files it writes
INPUT_OPTIONS = ("file", "recording", "recordings", "data", "calibration", "aero", "config", "rotors")
OUTPUT_OPTIONS = OUTPUT_NAMES
FOLDER_OUTPUTS = {("fly", "output"), ("demo", "out")}
"""Output options that name a folder (created if missing), not a file."""


def writes_files(parser) -> bool:
    """Whether a command has an option naming a file or folder it writes."""
    return any(a.dest in (*OUTPUT_OPTIONS, "plot_dir") and a.nargs != 0 and a.option_strings for a in parser._actions)


def add_force(parser) -> None:
    """``--force``, the same on every command that writes files: replace read-only outputs."""
    if writes_files(parser):
        parser.add_argument(
            "--force", action="store_true", help="replace an output file even if it is read-only (docs/reliability.md)"
        )


def _paths(value):
    if isinstance(value, (list, tuple)):
        return [v for x in value for v in _paths(x)]
    return [value] if isinstance(value, (str, Path)) else []


def check_outputs(args) -> None:
    """Before any work: refuse an output that names an input file (writing it would destroy the
    input), or that cannot be written as its kind says (data.files.output_target: a read-only
    file without --force, a missing folder, a socket...)."""
    from quadest.data.files import output_folder, output_target, refuse_overwriting_inputs
    from quadest.data.tables import csv_metadata_path

    inputs = [p for name in INPUT_OPTIONS for p in _paths(getattr(args, name, None))]
    outputs = {
        opt: getattr(args, name)
        for name, opt in OUTPUT_OPTIONS.items()
        if isinstance(getattr(args, name, None), (str, Path))
    }
    folders = {OUTPUT_OPTIONS[name] for command, name in FOLDER_OUTPUTS if command == args.command}
    data_on_stdout(args)
    outputs.update(_metadata_beside(outputs))  # a CSV's metadata file is written, and read, too
    inputs += [csv_metadata_path(p) for p in inputs if str(p).lower().endswith(".csv")]
    try:
        refuse_overwriting_inputs(outputs, inputs)
        _refuse_shared_outputs(outputs)
        for opt, path in outputs.items():
            if opt not in folders:
                output_target(path, force=getattr(args, "force", False))
            else:
                output_folder(path)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def _metadata_beside(outputs: dict) -> dict:
    """The metadata file each CSV output writes beside it (``-o e.csv``: ``e.csv-metadata.json``)."""
    from quadest.data.tables import csv_metadata_path

    return {
        f"{opt} {path}'s metadata": csv_metadata_path(path)
        for opt, path in outputs.items()
        if str(path).lower().endswith(".csv")
    }


def _refuse_shared_outputs(outputs: dict) -> None:
    """Two output options naming one file (``-o r.parquet --report r.parquet``): the second
    written would destroy the first."""
    seen: dict = {}
    for opt, path in outputs.items():
        key = os.path.realpath(path)
        if key in seen:
            raise ValueError(f"{opt} {path} is also the file of {seen[key]}; give each output its own file")
        seen[key] = opt


# options whose output needs an extra, checked before any work is done
EXTRA_OPTIONS = {
    "plot": ("matplotlib", "--plot"),
    "plot_dir": ("matplotlib", "--plot-dir"),
    "report": ("bokeh", "--report"),
}


def check_extras(args) -> None:
    """Say at once, in one line, which extra an asked-for output needs, not after the run."""
    for name, (module, option) in EXTRA_OPTIONS.items():
        if getattr(args, name, None):
            need(module, option)
    if args.command == "demo":
        need("matplotlib", "quadest demo's plots")
        need("bokeh", "quadest demo's report")


def _one_line_note(message, category, filename, lineno, line=None):
    """A library warning as the command line says it: one line, no source location."""
    return f"quadest: note: {message}\n"


def main(argv=None):
    """The command line; ``argv`` None: the program itself (``quadest``), whose Ctrl-C at any
    moment, its end included, is one line and exit code 130."""
    global _program
    entry = argv is None
    if entry:
        _program = True
        sys.unraisablehook = _interrupt_in_a_callback
        if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:  # kill: as Ctrl-C, the output being written removed
            signal.signal(signal.SIGTERM, signal.default_int_handler)
    try:
        code = run_command(list(sys.argv[1:] if entry else argv))
    except KeyboardInterrupt:  # while the parser is built, or an error is being said
        if entry:
            interrupted()
        print("quadest: interrupted", file=sys.stderr)
        return INTERRUPTED
    finally:
        if entry:  # from here to the process's end (Dask's and the interpreter's clean-up)
            signal.signal(signal.SIGINT, lambda *_: interrupted())
            if signal.getsignal(signal.SIGTERM) is signal.default_int_handler:
                signal.signal(signal.SIGTERM, lambda *_: interrupted())
    if entry:
        end(code)
    return code


def end(code) -> None:
    """The program's end, without the interpreter's teardown: the threads a command left are
    waited for and Python's exit functions run (Dask's, multiprocessing's, logging's), the
    output is flushed, then the process ends. The teardown would destroy what is still alive at
    exit, pyarrow's thread pools among them: a pool thread that then needs Python (to release a
    file or buffer it held) is stopped by the finalising interpreter inside C++ code, and the
    process aborts ("terminate called without an active exception", exit 134) or waits on it
    for ever (docs/reliability.md, exit)."""
    import atexit

    code = 0 if code is None else code if isinstance(code, int) else 1
    for thread in threading.enumerate():
        if thread is not threading.current_thread() and not thread.daemon:
            thread.join()
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):  # a reader that stopped (head); closed, or None from the start
            pass
    os._exit(code)


def run_command(argv: list) -> int:
    warnings.formatwarning = _one_line_note
    debug = "--debug" in argv
    argv = [a for a in argv if a != "--debug"]
    parser = build_parser()
    args = parser.parse_args(argv)  # a usage error exits here with code 2
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        set_verbosity(args)
        check_outputs(args)
        check_extras(args)
        load_libraries()
        from quadest.data.files import replacing_read_only
        from quadest.data.tables import use_system_allocator

        use_system_allocator()
        with replacing_read_only(getattr(args, "force", False)):
            return args.func(args)
    except BrokenPipeError:  # output piped into a command that stopped reading (head)
        return 0
    except KeyboardInterrupt:
        print("quadest: interrupted", file=sys.stderr)
        return INTERRUPTED
    except Exception as exc:  # noqa: BLE001 (every error ends in one line; --debug shows the traceback)
        if debug:
            traceback.print_exc()
        usage = isinstance(exc, (CliError, UsageError))
        if usage or isinstance(exc, (ValueError, OSError, MissingExtra)):
            msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        else:
            msg = (
                f"internal error ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}); "
                "please report it with the output of --debug"
            )
        print(f"quadest {args.command}: error: {msg}", file=sys.stderr)
        return 2 if usage else 1


if __name__ == "__main__":
    sys.exit(main())
