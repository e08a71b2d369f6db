"""The ``qogi`` command line."""

from __future__ import annotations

import argparse
import signal
import sys

from .._interrupts import Terminated, kept
from .._version import __version__
from ..errors import (
    EXIT_CODES_HELP,
    EXIT_DATA,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_USAGE,
    Cancelled,
    QogiError,
    is_no_space,
)


def cmd_gui(args: argparse.Namespace) -> int:
    import os

    if args.path is not None and not os.path.isfile(args.path):
        print(f"qogi gui: error: {args.path}: no such file", file=sys.stderr)
        return 2
    launch = _app("gui")
    if launch is None:
        print(
            "qogi gui: error: the viewer (qogi_gui) is not installed; install qogi with it: "
            "pip install 'qogi[gui]'",
            file=sys.stderr,
        )
        return 2
    scene = {
        k: v
        for k, v in (
            ("camera", args.camera),
            ("distance_m", args.distance),
            ("ambient_temperature_K", args.ambient_temperature),
            ("pressure_Pa", args.pressure),
        )
        if v is not None
    }
    return launch(args.path, scene=scene or None)


#: Where the command line finds the apps installed beside qogi (the viewer):
#: entry points of this group name a function ``(path, scene) -> exit status``.
APPS_GROUP = "qogi.apps"


def _app(name: str):
    """The app ``name`` of :data:`APPS_GROUP`, loaded, or None when no
    installed distribution provides it. The library never imports an app by
    name: the viewer sits above it and is found the way plugins are."""
    from importlib.metadata import entry_points  # only `qogi gui` pays for the scan

    for ep in entry_points(group=APPS_GROUP):
        if ep.name == name:
            return ep.load()
    return None


def build_parser() -> argparse.ArgumentParser:
    # Deferred for start-up: the commands' modules load numpy, h5py and the
    # engine. Imported here, inside main()'s handler, a Ctrl-C while they load
    # is "interrupted" (exit 130), not a traceback (test_interrupt).
    from . import (
        _cli_batch,
        _cli_camera,
        _cli_convert,
        _cli_envelope,
        _cli_info,
        _cli_pod,
        _cli_quantify,
        _cli_spectra,
        _cli_synth,
    )

    p = argparse.ArgumentParser(
        prog="qogi",
        description="Quantitative optical gas imaging: from radiometric MWIR video of a "
        "gas plume to an emission rate with an uncertainty.",
    )
    p.add_argument("--version", action="version", version=f"qogi {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    _cli_info.add_commands(sub)
    g = sub.add_parser(
        "gui",
        help="open the desktop viewer",
        description="Open the desktop viewer: play a recording, draw control surfaces with the "
        "mouse, set the analysis, run the quantification in the background and "
        "read, compare and export the emission rates. 'Load demo scene' in the "
        "window synthesises a known release to try it on.",
    )
    g.add_argument(
        "path",
        nargs="?",
        help="recording (.h5) or camera file (.seq, .csq, .jpg, .fff, .hcc) to open",
    )
    _cli_camera.add_scene_options(g)
    g.set_defaults(func=cmd_gui)

    _cli_spectra.add_commands(sub)

    _cli_synth.add_commands(sub)

    _cli_quantify.add_commands(sub)
    _cli_quantify.add_demo_command(sub)

    _cli_batch.add_commands(sub)

    _cli_envelope.add_commands(sub)

    _cli_convert.add_commands(sub)

    _cli_pod.add_commands(sub)
    _add_exit_codes(p)
    return p


class _Paragraphs(argparse.HelpFormatter):
    """argparse's formatter, keeping blank-line paragraph breaks in
    descriptions and epilogs (each paragraph still wrapped to the terminal)."""

    def _fill_text(self, text, width, indent):
        return "\n\n".join(
            super(_Paragraphs, self)._fill_text(p, width, indent) for p in text.split("\n\n")
        )


def _add_exit_codes(parser: argparse.ArgumentParser) -> None:
    """Every command's --help ends with the exit codes (qogi.errors), a
    paragraph of its own."""

    parser.epilog = f"{parser.epilog}\n\n{EXIT_CODES_HELP}" if parser.epilog else EXIT_CODES_HELP
    parser.formatter_class = _Paragraphs
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in set(action.choices.values()):
                _add_exit_codes(child)


def _on_sigterm(signum, frame):
    raise Terminated()


#: Ctrl-Cs seen by main()'s handler (which otherwise acts as Python's own).
_SIGINTS: list = []


def _on_sigint(signum, frame):
    _SIGINTS.append(signum)
    raise KeyboardInterrupt


def _interrupted(exc: BaseException) -> bool:
    """A Ctrl-C, also when it arrives wrapped: a KeyboardInterrupt while an
    extension module (the engine, numpy) initialises becomes pybind11's
    ``ImportError: initialization failed`` caused by it, numpy's own
    ImportError has it in its chain; inside numpy's C initialisation it can be
    lost altogether ("PyCapsule_Import could not import module 'datetime'"),
    so an ImportError after a Ctrl-C this run saw counts as one too."""
    if isinstance(exc, ImportError) and _SIGINTS:
        return True
    seen: set = set()
    todo: list = [exc]
    while todo:
        e = todo.pop()
        if e is None or id(e) in seen:
            continue
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        todo += [e.__cause__, e.__context__]
    return False


def _report_bug(command: str) -> None:
    import traceback

    traceback.print_exc()
    print(
        f"qogi {command}: internal error: this is a bug in qogi, not in your input. Please "
        "report it with the command line and the traceback above "
        f"(qogi {__version__}, Python {sys.version.split()[0]}).",
        file=sys.stderr,
    )


def main(argv: list[str] | None = None) -> int:
    """Runs one command; returns the exit status (qogi.errors.EXIT_CODES_HELP).

    A user's mistake or an environment problem (bad argument, missing file or
    line list, unwritable folder, unreadable data) is one line on stderr, exit
    2 or 3; Ctrl-C or SIGTERM exit 130 / 143 after the command's temporary files
    are gone; anything else is a bug: the traceback and a request to report it
    (exit 1).
    """
    _SIGINTS.clear()
    before = None
    try:
        if signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:  # ignored stays ignored
            before = signal.signal(signal.SIGINT, _on_sigint)
    except ValueError:  # not the main thread (embedded use): leave SIGINT alone
        pass
    try:
        return _main(argv)
    finally:
        if before is not None:
            signal.signal(signal.SIGINT, before)


def _main(argv: list[str] | None) -> int:
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        if not getattr(args, "func", None):
            parser.print_help()
            return EXIT_USAGE
        name = args.command + (
            f" {args.hitran_command}" if getattr(args, "hitran_command", None) else ""
        )
    except (KeyboardInterrupt, ImportError) as e:
        if not _interrupted(e):
            raise
        print("qogi: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    previous = None
    try:
        try:
            previous = signal.signal(signal.SIGTERM, _on_sigterm)
        except ValueError:  # not the main thread (embedded use): leave SIGTERM alone
            pass
        with kept():  # a Ctrl-C Python would drop (in a finaliser) still stops the run
            return int(args.func(args) or 0)
    except QogiError as e:
        print(f"qogi {name}: error: {e}", file=sys.stderr)
        return e.exit_code
    except Cancelled:
        print(f"qogi {name}: cancelled", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Terminated:
        print(f"qogi {name}: terminated", file=sys.stderr)
        return 128 + signal.SIGTERM
    except KeyboardInterrupt:
        print(f"qogi {name}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except MemoryError:
        print(
            f"qogi {name}: error: out of memory; use fewer frames (--frames) or a smaller input",
            file=sys.stderr,
        )
        return EXIT_DATA
    except (ValueError, OSError) as e:
        # Checks in the engine (std::invalid_argument) and the file system:
        # what the value or path is and what is accepted.
        text = str(e) or type(e).__name__
        if isinstance(e, OSError) and e.filename is not None and e.strerror:
            text = f"{e.filename}: {e.strerror}"
        if is_no_space(e):  # a write outside qogi's atomic writers (e.g. standard output)
            print(f"qogi {name}: error: no space left: {text}", file=sys.stderr)
            return EXIT_DATA
        print(f"qogi {name}: error: {text}", file=sys.stderr)
        return EXIT_USAGE
    except Exception as e:  # any other failure is a bug, reported as one  # noqa: BLE001
        if _interrupted(e):
            print(f"qogi {name}: interrupted", file=sys.stderr)
            return EXIT_INTERRUPTED
        _report_bug(name)
        return EXIT_INTERNAL
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    raise SystemExit(main())
