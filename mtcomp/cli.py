"""The ``mtcomp`` command line (README.md lists the commands).

Each command lives in ``mtcomp.commands.<name>`` with two functions: ``add_arguments(parser)`` and
``run(args) -> int``. Commands are imported only when used, so ``mtcomp machines`` stays fast.
Bad input anywhere raises :class:`mtcomp.errors.InputError`; here it becomes one line on stderr and
exit status 2, with no traceback.
"""
from __future__ import annotations

import argparse
import contextlib
import importlib
import sys

from .errors import InputError

#: command name -> (module under mtcomp.commands, one-line help)
COMMANDS = {
    "demo": ("demo", "the whole job on built-in defaults: simulate, identify, diagnose, compensate, render"),
    "machines": ("machines", "list the built-in machines"),
    "identify": ("identify", "fit the base error model to measurement files"),
    "diagnose": ("diagnose", "find what the fitted model gets wrong, extend it, measure the gain"),
    "compensate": ("compensate", "plan bounded per-block axis corrections for an NC program"),
    "study": ("study", "a correction study: many compensations on Dask, one results table and plots"),
    "predict": ("predict", "predict the readings of a measurement file from a model"),
    "render": ("render", "workpiece error map before and after compensation"),
    "iso230-2": ("iso230_2", "ISO 230-2 evaluation of laser positioning runs"),
    "export": ("export", "the controller's own compensation tables (LinuxCNC, Siemens, Heidenhain, "
               "Fanuc, ISG, Klipper)"),
}


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # usage errors: one line, exit 2
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        raise SystemExit(2)


class _StoreOnce(argparse._StoreAction):
    """An option that takes one value: given twice (``-o a.json -o b.json``, ``--format linuxcnc
    --format siemens``) it is a usage error, where argparse would let the last one win silently.
    Repeatable options (``--tool-length H1=.. --tool-length H2=..``) append and are not affected."""

    def __call__(self, parser, namespace, values, option_string=None):
        given = getattr(namespace, "_given_once", set())
        if self.dest in given:
            parser.error(f"{'/'.join(self.option_strings)} given twice (it takes one value; the "
                         "second would replace the first)")
        given.add(self.dest)
        setattr(namespace, "_given_once", given)
        super().__call__(parser, namespace, values, option_string)


def _store_once(parser: argparse.ArgumentParser) -> None:
    """Make every single-valued option of ``parser`` a :class:`_StoreOnce`."""
    for action in parser._actions:
        if type(action) is argparse._StoreAction and action.option_strings:
            action.__class__ = _StoreOnce


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The command line's parser. ``command``: the one command whose arguments are added (its
    module imported; the others are listed by name and help only, their modules not imported: a
    run of one command does not import the others', e.g. compensate not export's tables); None:
    every command's."""
    from . import __version__
    parser = _Parser(prog="mtcomp", description="Compensation planner for the geometric errors of "
                     "CNC machine tools.")
    parser.add_argument("--version", action="version", version=f"mtcomp {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for name, (module, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        mod = _command_module(module, optional=True) if command in (None, name) else None
        if mod is not None:
            mod.add_arguments(p)
            _store_once(p)
        p.set_defaults(_module=module)
    return parser


def _command_named(argv: list[str]) -> str | None:
    """The command an argument list runs: its first word that is not an option (the top level
    takes no option with a value), None when that is no command (argparse then says what is
    wrong, with every command's parser built)."""
    first = next((a for a in argv if not a.startswith("-")), None)
    return first if first in COMMANDS else None


def _command_module(module: str, optional: bool = False):
    try:
        return importlib.import_module(f"mtcomp.commands.{module}")
    except ModuleNotFoundError as exc:
        if optional and exc.name == f"mtcomp.commands.{module}":
            return None
        raise


class Terminated(BaseException):
    """SIGTERM (``kill``, ``timeout``) raised as an exception, so that a command unwinds as on
    Ctrl-C: its temporary output files are removed, nothing partial is left."""


@contextlib.contextmanager
def _terminate_as_exception():
    """SIGTERM raises :class:`Terminated` while the block runs (in the main thread only: elsewhere
    signal handlers cannot be set, and the default stays)."""
    import signal
    import threading
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise Terminated

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(_command_named(argv))
    args = parser.parse_args(argv)
    vars(args).pop("_given_once", None)
    mod = _command_module(args._module, optional=True)
    if mod is None:
        sys.stderr.write(f"mtcomp {args.command}: this command is not available in this build\n")
        return 2
    try:
        try:
            with _terminate_as_exception():
                rc = int(mod.run(args) or 0)
            sys.stdout.flush()              # a closed pipe shows here, not at the interpreter's exit
            return rc
        except InputError as exc:
            sys.stderr.write(f"mtcomp {args.command}: {exc.one_line()}\n")
            return 2
        except KeyboardInterrupt:
            sys.stderr.write("mtcomp: interrupted\n")
            return 130
        except Terminated:
            sys.stderr.write("mtcomp: terminated\n")
            return 143
    except BrokenPipeError:
        # the reader of the output went away (`mtcomp ... | head`): what was written is whole (atomic
        # outputs), files not yet written are not; stop quietly, with nothing left for the
        # interpreter's final flush of stdout and stderr to fail on
        import os
        devnull = os.open(os.devnull, os.O_WRONLY)
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(OSError, ValueError):
                os.dup2(devnull, stream.fileno())
        return 141


if __name__ == "__main__":
    sys.exit(main())
