"""The ``scanamp`` command line: a thin layer over the library.

Commands are discovered from the modules of :mod:`scanamp.commands`. A module
defines ``NAME`` (``"scene"``), optionally ``GROUP`` (``"capture"`` for
``scanamp capture laser``), ``HELP``, ``add_arguments(parser)`` and
``run(args) -> int``. A module with ``CONFIG`` (its config dataclass, see
:mod:`core.config`) gets ``--config FILE.toml`` and one flag per declared option
(:mod:`scanamp.options`), and is called as ``run(args, config)`` with the effective
config. Errors: bad input exits 2 with one line ``error: ...``;
an algorithm that failed or an internal error exits 1 (traceback under --debug).
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import pkgutil
import sys
import traceback

os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
import cv2  # noqa: E402,F401  (cv2 before pycolmap: pycolmap's libpng breaks cv2.imwrite)

from core.validate import InputError  # noqa: E402
from scanamp.options import add_config_flags, config_from_args  # noqa: E402

log = logging.getLogger("scanamp")


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2, like every other bad input
        self.print_usage(sys.stderr)
        sys.stderr.write(f"error: {message}\n")
        sys.exit(2)


def _command_modules():
    import scanamp.commands as pkg

    for info in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda i: i.name):
        if not info.name.startswith("_"):
            yield importlib.import_module(f"scanamp.commands.{info.name}")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="scanamp", description=(
        "Simulate 3-D acquisition of procedural scenes, reconstruct and evaluate meshes, "
        "and amplify them with procedural modeling and animation."))
    parser.add_argument("--debug", action="store_true", help="show tracebacks and debug logs")
    parser.add_argument("-q", "--quiet", action="store_true", help="only warnings and errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    groups: dict[str, argparse._SubParsersAction] = {}
    group_help = {"capture": "render a virtual capture of a scene",
                  "reconstruct": "reconstruct a mesh from a capture",
                  "simulate": "run a procedural animation",
                  "procgen": "procedural modeling generators",
                  "calibrate": "calibrate a real camera or stereo pair from board photos"}
    for mod in _command_modules():
        group = getattr(mod, "GROUP", None)
        target = sub
        if group:
            if group not in groups:
                gp = sub.add_parser(group, help=group_help.get(group, group))
                groups[group] = gp.add_subparsers(dest="kind", metavar="KIND",
                                                  parser_class=_Parser)
                groups[group].required = True
            target = groups[group]
        p = target.add_parser(mod.NAME, help=getattr(mod, "HELP", None),
                              description=getattr(mod, "HELP", None))
        mod.add_arguments(p)
        config_cls = getattr(mod, "CONFIG", None)
        if config_cls is not None:
            add_config_flags(p, config_cls)
        p.set_defaults(_run=mod.run, _config_cls=config_cls)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.DEBUG if args.debug else (logging.WARNING if args.quiet else logging.INFO)
    logging.basicConfig(level=level, format="%(message)s", stream=sys.stderr)
    if not args.debug:
        for noisy in ("numba", "matplotlib", "PIL", "distributed", "asyncio"):
            logging.getLogger(noisy).setLevel(logging.WARNING)
    if not args.quiet:
        from core import progress

        progress.enable(sys.stderr.isatty())
    try:
        if args._config_cls is not None:
            return int(args._run(args, config_from_args(args._config_cls, args)) or 0)
        return int(args._run(args) or 0)
    except (InputError, ValueError, FileNotFoundError, IsADirectoryError,
            NotADirectoryError) as exc:
        if args.debug:
            traceback.print_exc()
        msg = str(exc)
        if isinstance(exc, OSError) and exc.filename:
            msg = f"{exc.filename}: {exc.strerror}"
        sys.stderr.write(f"error: {msg}\n")
        return 2
    except KeyboardInterrupt:
        sys.stderr.write("error: interrupted\n")
        return 130
    except Exception as exc:  # RuntimeError: an algorithm failed; anything else: a bug
        if args.debug:
            traceback.print_exc()
        if isinstance(exc, RuntimeError):  # the message is the diagnosis
            sys.stderr.write(f"error: {exc}\n")
        else:
            sys.stderr.write(f"error: internal {type(exc).__name__}: {exc} (run with --debug "
                             "for the traceback)\n")
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
