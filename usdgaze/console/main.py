"""The ``usdgaze`` command line. Exit codes: 0 done, 2 bad input (one line on stderr), 1 internal error,
3 ``validate`` found problems."""

from __future__ import annotations

import ast
import importlib
import importlib.util
import os
import signal
import sys
import threading
import traceback

import click

from usdgaze import __version__
from usdgaze.errors import Interrupted, UsdGazeError
from usdgaze.files.signals import later_if_importing, stops_to_handle

EXIT_BAD_INPUT = 2
EXIT_INTERNAL = 1


def _fail(message: str) -> None:
    click.echo(f"usdgaze: error: {' '.join(str(message).split())}", err=True)


# One module per command, imported only when that command runs, so ``usdgaze --help`` stays cheap.
_COMMANDS = {
    "apply": ("usdgaze.console.apply", "apply"),
    "inspect": ("usdgaze.console.inspect", "inspect"),
    "dump-map": ("usdgaze.console.dump_map", "dump_map"),
    "plugin-path": ("usdgaze.console.plugin_path", "plugin_path"),
    "build-map": ("usdgaze.console.build_map", "build_map"),
    "physics-model": ("usdgaze.console.physics_model", "physics_model"),
    "plot": ("usdgaze.console.plot", "plot"),
    "preview": ("usdgaze.console.preview", "preview"),
    "validate": ("usdgaze.console.validate", "validate"),
    "batch": ("usdgaze.console.batch", "batch"),
    "attend": ("usdgaze.console.attend", "attend"),
}


def _short_help(name: str) -> str:
    """First line of a command's docstring, read from its source so ``--help`` imports no command."""
    module, attr = _COMMANDS[name]
    try:
        spec = importlib.util.find_spec(module)
        tree = ast.parse(open(spec.origin, encoding="utf-8").read())
        doc = next(ast.get_docstring(n) for n in tree.body
                   if isinstance(n, (ast.FunctionDef, ast.ClassDef)) and n.name == attr) or ""
    except (ImportError, OSError, SyntaxError, StopIteration, AttributeError, TypeError):
        return ""
    return doc.strip().split("\n")[0]


class _LazyGroup(click.Group):
    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(_COMMANDS)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        names = self.list_commands(ctx)
        limit = formatter.width - 6 - max(map(len, names), default=0)  # as click.Group lays it out
        rows = [(name, click.utils.make_default_short_help(_short_help(name), limit)) for name in names]
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name not in _COMMANDS:
            return None
        module, attr = _COMMANDS[name]
        command = getattr(importlib.import_module(module), attr)
        if not getattr(command, "_refuses_repeats", False):
            parse = command.parse_args

            def parse_args(ctx: click.Context, args: list[str]) -> list[str]:
                _refuse_repeats(command, args)
                return parse(ctx, args)

            command.parse_args, command._refuses_repeats = parse_args, True
        return command


def _refuse_repeats(command: click.Command, args: list[str]) -> None:
    """An option of one value given twice is refused: click keeps the last without a word (two
    --skel-root ran the second character only)."""
    given = args[:args.index("--")] if "--" in args else args
    for p in command.params:
        if not isinstance(p, click.Option) or p.multiple or p.count or p.is_flag:
            continue
        names = p.opts + p.secondary_opts
        n = sum(a in names or any(a.startswith(o + "=") for o in names if o.startswith("--")) for a in given)
        if n > 1:
            raise click.UsageError(f"{p.opts[0]} is given {n} times; it takes one value")


@click.group(cls=_LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="usdgaze")
def cli() -> None:
    """Add realistic gaze shifts to UsdSkel animation as a non-destructive override layer."""


class _Stops:
    """Stopping signals (:data:`usdgaze.files.signals.STOPS`) while a command runs, wherever no writer's
    transaction handles them: one line and 128 + the signal (the process ends at once with ``hold``, else
    :class:`Interrupted` is raised), and nothing once the command's outputs are in place (all that is left is its report). ``hold``: the
    process ends after the command, so they are ignored from its end on (Python puts back the default
    action, a kill, for its own handlers while it shuts down, and any thread, USD's included, may
    receive the signal)."""

    def __init__(self, hold: bool = False) -> None:
        self.commits = self._commits()
        self.hold = hold
        self.saved: dict = {}

    @staticmethod
    def _commits() -> int:
        # Not imported (or half imported, a signal landing in its import): nothing committed yet.
        outputs = getattr(sys.modules.get("usdgaze.files.transaction"), "Outputs", None)
        return outputs.commits if outputs else 0

    def __enter__(self) -> "_Stops":
        if threading.current_thread() is threading.main_thread():  # Python's signal handlers live there
            for sig in stops_to_handle():
                self.saved[sig] = signal.signal(sig, self._on_signal)
        return self

    def _on_signal(self, signum, frame) -> None:
        if self._commits() != self.commits:
            return
        if self.hold:
            # The process is the command and no writer holds a temporary (a writer's own handler
            # runs while one does): end it here. Raised instead, the stop could land inside an import,
            # where USD's module loader swallows it or leaves a module half made.
            os.write(2, f"{_interrupted_line(Interrupted(signum))}\n".encode())
            os._exit(128 + signum)
        if later_if_importing(signum, frame):  # raised there, the import could swallow it
            return
        raise Interrupted(signum)

    def __exit__(self, *exc) -> None:
        for sig, handler in self.saved.items():
            signal.signal(sig, signal.SIG_IGN if self.hold else handler)


def main(argv: list[str] | None = None, hold: bool = False) -> int:
    """Run the CLI and map failures to exit codes (2 bad input, 1 internal, 128 + a stopping signal).

    ``hold``: the process ends after this (the console script): a signal arriving once the outcome is
    known is ignored instead of turning the exit into a kill or a traceback."""
    with _Stops(hold):
        try:
            code = _run(argv)
        except Interrupted as exc:  # it arrived while another outcome was being said
            code = _interrupted(exc)
    return code


def entry() -> None:
    """The ``usdgaze`` console script and ``python -m usdgaze``."""
    sys.exit(main(hold=True))


def _interrupted_line(exc: Interrupted) -> str:
    return f"usdgaze: error: interrupted by {exc}; {exc.detail}"


def _interrupted(exc: Interrupted) -> int:
    click.echo(_interrupted_line(exc), err=True)
    return 128 + exc.signum


def _run(argv: list[str] | None) -> int:
    from usdgaze.process import tune_allocator

    try:
        tune_allocator()
        code = cli.main(args=argv, prog_name="usdgaze", standalone_mode=False)
    except UsdGazeError as exc:
        _fail(str(exc))
        return EXIT_BAD_INPUT
    except Interrupted as exc:  # the writer, if any, has removed every temporary
        return _interrupted(exc)
    except KeyboardInterrupt:  # SIGINT from a thread or library that raised Python's own
        _fail("interrupted by SIGINT; nothing was written")
        return 130
    except click.exceptions.NoArgsIsHelpError as exc:  # plain ``usdgaze``: the help, as --help gives it
        click.echo(exc.ctx.get_help() if exc.ctx else exc.format_message())
        return 0
    except click.exceptions.Abort:
        _fail("aborted")
        return EXIT_BAD_INPUT
    except click.ClickException as exc:
        _fail(exc.format_message())
        return EXIT_BAD_INPUT
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except SystemExit as exc:
        if exc.code == 1 and type(sys.stdout).__name__.endswith("PacifyFlushWrapper"):
            # click's answer to a reader that went away (`| head`), silent: exit as a process that
            # SIGPIPE stopped does, not with the 1 of a bug.
            return 128 + signal.SIGPIPE
        raise
    except OSError as exc:
        if not _stdout_failed(exc):
            return _bug(exc)
        from usdgaze.files.transaction import os_reason

        _fail(f"cannot write to standard output ({os_reason(exc)})")
        return EXIT_BAD_INPUT
    except Exception as exc:
        return _bug(exc)
    # A command's own exit code (``validate`` exits 3 on problems), which click returns here.
    return code if isinstance(code, int) else 0


def _stdout_failed(exc: OSError) -> bool:
    """Whether ``exc`` is standard output refusing what is echoed to it (a full disk); it is then pointed
    at the null device, so that Python's own flush at exit says nothing more."""
    tb = exc.__traceback__
    while tb is not None and tb.tb_next is not None:
        tb = tb.tb_next
    frame = tb.tb_frame if tb is not None else None
    if frame is None or frame.f_code.co_name != "echo" or "click" not in frame.f_code.co_filename:
        return False
    if getattr(frame.f_locals.get("file"), "name", None) != "<stdout>":
        return False
    sys.stdout = open(os.devnull, "w")
    return True


def _bug(exc: Exception) -> int:
    """A bug: said in one line, the traceback kept for whoever debugs it."""
    if os.environ.get("USDGAZE_DEBUG"):
        traceback.print_exception(exc)
    _fail(f"internal error: {type(exc).__name__}: {exc} (set USDGAZE_DEBUG=1 for the traceback)")
    return EXIT_INTERNAL


if __name__ == "__main__":
    entry()
