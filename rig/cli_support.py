"""Shared command-line plumbing for the ``rig`` and ``lts`` apps.

Numbers go to stdout as one JSON object (``--json``); human text and progress go to stderr. Bad
input ends the command with a one-line error and exit status 2, never a traceback.
"""

from __future__ import annotations

import inspect
import json
import logging
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

import click
import typer
from rich.console import Console
from rich.markup import escape

from rig.errors import InputError, OutOfRangeError
from rig.native_output import native_output_to_stderr
from rig.plain import plain_data
from rig.version import package_version

#: Console for human-readable output and progress bars (stderr, so stdout stays machine-readable).
console = Console(stderr=True, soft_wrap=True)

EXIT_BAD_INPUT = 2
#: How every app's ``--help`` reads its docstrings: as Markdown, which joins a paragraph's source
#: lines into one (typer's default, Rich markup, keeps each source line break, so the paragraphs
#: after the first break at the code's line width rather than the terminal's).
HELP_MARKUP = "markdown"
#: Usage errors: click's, and those of the copy of click that typer >= 0.29 carries.
_USAGE_ERRORS = (click.ClickException, getattr(typer, "TyperException", click.ClickException))

#: The real stdout while a ``--json`` command runs with file descriptor 1 pointed at stderr.
_json_stream: TextIO | None = None


def emit_json(obj: dict[str, Any]) -> None:
    """Print ``obj`` as one JSON object on stdout (numpy values converted, NaN/Inf as null)."""
    stream = _json_stream or sys.stdout
    stream.write(json.dumps(plain_data(obj, nonfinite_as_none=True)) + "\n")
    stream.flush()


def _run_with_json_stdout(app: typer.Typer, prog_name: str) -> Any:
    """Run ``app``; with ``--json`` on the command line everything but :func:`emit_json`'s object
    goes to stderr, native libraries' output included."""
    global _json_stream
    if "--json" not in sys.argv[1:]:
        return app(prog_name=prog_name, standalone_mode=False)
    with native_output_to_stderr() as real_stdout:
        _json_stream = real_stdout
        try:
            return app(prog_name=prog_name, standalone_mode=False)
        finally:
            _json_stream = None


class _ConsoleLogHandler(logging.Handler):
    """The toolkit's log records (e.g. which clock times a bag's topic) as plain lines on stderr."""

    def emit(self, record: logging.LogRecord) -> None:
        console.print(record.getMessage(), highlight=False, markup=False)


def _show_library_logs() -> None:
    """Show INFO and above of the ``rig`` loggers on stderr (once, however often called)."""
    logger = logging.getLogger("rig")
    if not any(isinstance(h, _ConsoleLogHandler) for h in logger.handlers):
        logger.addHandler(_ConsoleLogHandler())
        logger.setLevel(logging.INFO)


def _print_usage_error(exc: Exception) -> None:
    """Click's short usage of the command (when the error knows it), then the error in one line;
    nothing more for a group called without a command, whose help is already printed."""
    message = exc.format_message()  # type: ignore[attr-defined]
    if not message:
        return
    ctx = getattr(exc, "ctx", None)
    if ctx is not None:
        console.print(ctx.get_usage(), highlight=False, markup=False)
        console.print(f"Try '{ctx.command_path} --help' for help.", highlight=False, markup=False)
    console.print(f"error: {message}", highlight=False, markup=False)


def _flags_show_no_type() -> None:
    """Typer's rich help lists a flag (``--json``, ``--help``) with the type ``<bool>``, as if it
    took a value (``--json true`` is then a usage error); its plain help shows none, as here."""
    option = getattr(typer.core, "TyperOption", None)
    shown = getattr(option, "display_type_rich", None)
    if shown is None or getattr(shown, "flags_show_no_type", False):
        return

    def display_type_rich(self: Any, ctx: click.Context) -> str | None:
        return None if self.is_flag and not self.count else shown(self, ctx)

    display_type_rich.flags_show_no_type = True  # type: ignore[attr-defined]
    option.display_type_rich = display_type_rich  # type: ignore[union-attr]


def tidy_help(app: typer.Typer) -> None:
    """Three conventions of the help screens, for every command of ``app`` and of its sub-apps:

    - a command without a short help gets the first paragraph of its help (or docstring) as one
      line: Typer lists a command by that paragraph with the docstring's line breaks kept, so a
      command list showed ragged lines broken mid-phrase;
    - an argument without a metavar shows as its name in capitals (``OUT_DIR``), as the help texts
      write it, instead of the Python parameter's name in the usage line (``{out_dir}``);
    - a flag shows no type (:func:`_flags_show_no_type`).
    """
    _flags_show_no_type()
    for command in app.registered_commands:
        text = command.help or inspect.getdoc(command.callback) or ""
        if command.short_help is None and text:
            command.short_help = " ".join(text.split("\n\n")[0].split())
        for name, parameter in inspect.signature(command.callback).parameters.items():
            if isinstance(parameter.default, typer.models.ArgumentInfo) and parameter.default.metavar is None:
                parameter.default.metavar = name.upper()
    for group in app.registered_groups:
        if group.typer_instance is not None:
            tidy_help(group.typer_instance)


def run_app(app: typer.Typer, prog_name: str) -> Callable[[], None]:
    """Wrap a Typer app into a console-script entry point that reports bad input in one line (its
    help screens tidied by :func:`tidy_help`)."""
    tidy_help(app)

    def main() -> None:
        _show_library_logs()
        try:
            # Outside standalone mode Click returns the code of a typer.Exit instead of raising it.
            code = _run_with_json_stdout(app, prog_name)
            if isinstance(code, int) and code != 0:
                sys.exit(code)
        except (InputError, OutOfRangeError) as exc:
            # The message is text, not markup: a path or an extra's name in brackets must stay.
            console.print(f"[bold red]error:[/] {escape(str(exc))}", highlight=False, markup=True)
            sys.exit(EXIT_BAD_INPUT)
        except typer.Exit as exc:
            sys.exit(exc.exit_code)
        except typer.Abort:
            console.print("aborted")
            sys.exit(130)
        except KeyboardInterrupt:
            console.print("interrupted")
            sys.exit(130)
        except _USAGE_ERRORS as exc:  # they carry their own message and exit code
            _print_usage_error(exc)
            sys.exit(exc.exit_code)
        except OSError as exc:  # a full disk, a vanished folder: say which file, no traceback
            where = f"{exc.filename}: " if exc.filename else ""
            console.print(f"error: {where}{exc.strerror or exc}", highlight=False, markup=False)
            sys.exit(1)

    return main


def version_callback(value: bool) -> None:
    """Typer callback for ``--version``."""
    if value:
        typer.echo(f"lidar-ts {package_version()}")
        raise typer.Exit()


#: The ``--version`` option both apps take (``version: bool = VERSION_OPTION``).
VERSION_OPTION = typer.Option(
    False, "--version", callback=version_callback, is_eager=True, help="Print the version and exit."
)


def _no_file_above(path: Path | None) -> Path | None:
    """``path`` unless one of the folders it would be made in is a file."""
    if path is not None:
        for folder in path.parents:
            if folder.exists():
                if not folder.is_dir():
                    raise typer.BadParameter(f"{folder} is a file, not a folder")
                break
    return path


def _in_existing_folder(path: Path | None) -> Path | None:
    if path is not None and not _no_file_above(path).parent.is_dir():
        raise typer.BadParameter(f"the folder {path.parent} does not exist")
    return path


def _path_parameter(default: Any, flags: tuple[str, ...], help: str, **checks: Any) -> Any:
    """A Typer option with ``flags``, or an argument without them, carrying click's path ``checks``."""
    if flags:
        return typer.Option(default, *flags, help=help, **checks)
    return typer.Argument(default, help=help, **checks)


def output_file_option(default: Any, *flags: str, help: str) -> Any:
    """A Typer option (or, with no ``flags``, argument) naming a file to write: refused on the
    command line (exit 2) when it is a folder or its folder does not exist (or is a file), before
    any work."""
    return _path_parameter(default, flags, help, dir_okay=False, callback=_in_existing_folder)


def output_folder_option(default: Any, *flags: str, help: str) -> Any:
    """A Typer option (or, with no ``flags``, argument) naming a folder to write into (made when
    missing): refused on the command line (exit 2) when it or a folder above it is a file, before
    any work."""
    return _path_parameter(default, flags, help, file_okay=False, callback=_no_file_above)
