"""The `geoterrain` Click group: shared flags, one-line errors and exit codes."""

from __future__ import annotations

import importlib
import logging
import signal
import sys
import traceback
import warnings

import click

from geoterrain._version import __version__
from geoterrain.exceptions import GeoterrainError

# command name → its module in geoterrain.cli, imported when the command runs (or for
# --help): `geoterrain render` no longer imports the preprocess's and bench's modules
# (about 0.2 s of a 2.7 s cold render)
COMMANDS = {"preprocess": "preprocess", "info": "info", "mesh": "mesh", "export": "export",
            "export-raster": "export_raster", "tiles": "tiles", "render": "render",
            "view": "view", "bench": "bench", "synth": "synth", "edit": "edit", "query": "query",
            "profile": "profile", "viewshed": "viewshed", "contours": "contours",
            "serve": "serve"}


def one_line(text: object) -> str:
    r"""``text`` as one printable line: newlines and runs of blanks as one space, control
    characters as "?", bytes that are not UTF-8 (a file name's) as escapes, at most 400
    characters.

    Examples
    --------
    >>> one_line("a\n  b\x07 c\udcff")
    'a b? c\\udcff'
    """
    s = " ".join(str(text).split())
    s = s.encode("utf-8", "backslashreplace").decode("utf-8")
    s = "".join(c if c.isprintable() else "?" for c in s)
    return s if len(s) <= 400 else s[:397] + "..."


class Group(click.Group):
    """Turns library errors into one line and an exit code (2 usage, 1 data); loads each
    command's module on first use. Click's own usage errors (an unknown option, a value
    its type refuses) are one line too, naming the command's ``--help``."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True,
             **extra):
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, False, **extra)
        try:
            rv = super().main(args, prog_name, complete_var, False, **extra)
        except click.exceptions.NoArgsIsHelpError as exc:  # the help itself, as Click shows it
            exc.show()
            sys.exit(exc.exit_code)
        except click.exceptions.UsageError as exc:
            where = exc.ctx.command_path if exc.ctx is not None else prog_name or "geoterrain"
            msg = one_line(exc.format_message()).rstrip(".")
            click.echo(f"Error: {msg}; see '{where} --help'", err=True)
            sys.exit(exc.exit_code)
        except click.ClickException as exc:
            click.echo(f"Error: {one_line(exc.format_message())}", err=True)
            sys.exit(exc.exit_code)
        except click.exceptions.Abort:
            click.echo("Aborted; nothing was written.", err=True)
            sys.exit(1)
        sys.exit(rv if isinstance(rv, int) else 0)

    def list_commands(self, ctx) -> list[str]:
        return sorted(COMMANDS)

    def get_command(self, ctx, name: str):
        mod = COMMANDS.get(name)
        if mod is None:
            return None
        return importlib.import_module(f"geoterrain.cli.{mod}").command

    def resolve_command(self, ctx, args):
        name, cmd, rest = super().resolve_command(ctx, args)
        if not any(a in ("-h", "--help") for a in rest):
            # a first run: say that kernels compile, with a bar (cli/options.py)
            from geoterrain.cli.compilebar import CompileBar

            bar = CompileBar(name, bool(ctx.params.get("quiet")))
            ctx.meta["geoterrain.compile_bar"] = bar.__enter__()
        return name, cmd, rest

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except GeoterrainError as exc:
            click.echo(f"Error: {one_line(exc.cli or exc)}", err=True)
            ctx.exit(exc.exit_code)
        except (click.exceptions.Exit, click.exceptions.Abort, click.ClickException):
            raise
        except KeyboardInterrupt as exc:
            click.echo("Interrupted; nothing was written.", err=True)
            ctx.exit(128 + getattr(exc, "signum", signal.SIGINT))
        except MemoryError:
            click.echo("Error: out of memory; use a smaller DEM or a larger machine", err=True)
            ctx.exit(1)
        except Exception as exc:  # noqa: BLE001 - the last line of defence: never a traceback
            if (ctx.obj or {}).get("verbose", 0) > 1:
                traceback.print_exc()
            first = str(exc).splitlines()[0] if str(exc) else ""
            click.echo(f"Error: internal error {type(exc).__name__}: {one_line(first)} "
                       "(re-run with -vv for the traceback and report it)", err=True)
            ctx.exit(1)
        finally:
            bar = ctx.meta.pop("geoterrain.compile_bar", None)
            if bar is not None:
                bar.__exit__(None, None, None)


@click.group(cls=Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="geoterrain")
@click.option("-v", "--verbose", count=True, help="More output (-vv: tracebacks).")
@click.option("-q", "--quiet", is_flag=True, help="No progress bars or summaries.")
@click.pass_context
def cli(ctx, verbose, quiet):
    """Turn real elevation data into fast, accurate 3-D terrain.

    \b
    Typical session:
      geoterrain preprocess dem.tif           # → dem.geoterrain
      geoterrain info dem.geoterrain
      geoterrain mesh dem.geoterrain -o dem.ply --max-error 1
      geoterrain render dem.geoterrain -o view.png
      geoterrain query dem.geoterrain --at X,Y       # heights, profiles, viewsheds,
      geoterrain contours dem.geoterrain --interval 50 -o c.gpkg   # contours: the analysis

    Run `geoterrain COMMAND --help` for each command's options.
    """
    ctx.ensure_object(dict)
    ctx.obj["verbose"] = verbose
    ctx.obj["quiet"] = quiet
    logging.basicConfig(level=logging.DEBUG if verbose > 1 else
                        logging.INFO if verbose else logging.WARNING,
                        format="%(levelname)s: %(message)s")
    if verbose < 2:  # -vv: Python's own warnings, with their file and line
        warnings.showwarning = _one_line_warning


# library warnings that mean nothing to a user of the command line: a raster without a
# geotransform is said in geoterrain's own words (--pixel-size), and matplotlib's missing
# glyphs only change how an overlay's text looks
_SILENT = ("NotGeoreferencedWarning", "Glyph")


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """A library's warning as one line on stderr, without its source path."""
    text = one_line(message)
    if any(s in category.__name__ or s in text for s in _SILENT):
        return
    click.echo(f"warning: {text}", err=True)


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP: unwinds like Ctrl-C, so partial files are removed."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _on_signal(signum, frame) -> None:
    raise Terminated(signum)


def _catch_signals() -> None:
    for sig in (signal.SIGTERM, getattr(signal, "SIGHUP", None)):
        if sig is not None:
            try:
                signal.signal(sig, _on_signal)
            except (ValueError, OSError):  # not the main thread
                pass


def main() -> None:
    _catch_signals()
    # numba's and VTK's start without what a command does not use (core/startup.py);
    # nothing of numba or VTK is imported here
    from geoterrain.core import startup

    startup.install()
    cli(prog_name="geoterrain")


if __name__ == "__main__":
    sys.exit(main())
