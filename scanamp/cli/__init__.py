"""The ``scanamp`` command line: a thin layer over the library.

Commands are discovered from the modules of this room (``scanamp/cli/``; an
underscored module is a helper, not a command). A module defines ``NAME`` (``"scene"``),
optionally ``GROUP`` (``"simulate"`` for ``scanamp simulate boids``), ``HELP``,
``add_arguments(parser)`` and ``run(args) -> int``; or ``commands()``, a list of objects
with those attributes (``capture`` and ``reconstruct`` make one per registered
acquisition method, :mod:`scanamp.methods`). A module with ``CONFIG`` (its config dataclass, see
:mod:`core.config`) gets ``--config FILE.toml`` and one flag per declared option
(:mod:`scanamp.cli._options`), and is called as ``run(args, config)`` with the effective
config. Errors: bad input exits 2 with one line ``error: ...``;
an algorithm that failed or an internal error exits 1 (traceback under --debug).

Outputs never destroy (:mod:`core.runs.outputs`). A command whose parser has ``--out`` gets
``--overwrite``; before it runs, its output is checked against what exists and against
every input path among its arguments. ``OUTPUT`` says what ``--out`` is: ``"dir"``
(default), ``"file"``, or ``"resume"`` (a folder the same command may extend without
``--overwrite``: a study); ``OUTPUT_DEST`` names another argument holding the output
(``"json"``), and ``companions(args, config)`` lists files or folders written beside a file
output. The output folder gets the manifest that marks it as scanamp's.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import logging
import os
import pkgutil
import sys
import traceback
from pathlib import Path

import cv2  # noqa: E402,F401  (cv2 before pycolmap: pycolmap's libpng breaks cv2.imwrite)

import core  # noqa: E402,F401  (first: it sets the threading environment)
from core.validate import InputError  # noqa: E402
from scanamp.cli._options import add_config_flags, config_from_args  # noqa: E402

log = logging.getLogger("scanamp")

__all__ = ["main", "build_parser", "versions", "add_config_flags", "config_from_args"]


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2, like every other bad input
        sys.stderr.write(f"error: {self.prog}: {message} (see {self.prog} --help)\n")
        sys.exit(2)


class _FinalPaths(logging.Filter):
    """core.files writes into ".NAME.scanamp-tmp-XXXXXXXX" beside NAME and renames it into
    place: messages name the final path, never the temporary one."""

    def filter(self, record: logging.LogRecord) -> bool:
        from core.files import TEMP_NAME

        msg = record.getMessage()
        if "-tmp-" in msg or "-old-" in msg:
            record.msg, record.args = TEMP_NAME.sub(r"\1", msg), None
        return True


def versions() -> dict[str, str]:
    """scanamp's version and those of its core dependencies (``scanamp --version``)."""
    from importlib import metadata

    from core.files import version

    found = {"scanamp": version()}
    for dist in ("numpy", "opencv-contrib-python-headless", "open3d", "pycolmap", "pymeshlab",
                 "pyvista"):
        try:
            found[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            found[dist] = "not installed"
    return found


class _Version(argparse.Action):
    def __call__(self, parser, namespace, values, option_string=None):
        v = versions()
        sys.stdout.write(f"scanamp {v.pop('scanamp')} (Python {sys.version.split()[0]})\n")
        for name, ver in v.items():
            sys.stdout.write(f"  {name} {ver}\n")
        parser.exit(0)


def _commands():
    """Every command: each public module of this room is one, or makes several with
    ``commands()`` (``capture`` and ``reconstruct``: one per registered method)."""
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda i: i.name):
        if info.name.startswith("_"):
            continue
        mod = importlib.import_module(f"{__name__}.{info.name}")
        yield from (mod.commands() if hasattr(mod, "commands") else [mod])


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="scanamp", description=(
        "Simulate 3-D acquisition of procedural scenes, reconstruct and evaluate meshes, "
        "and amplify them with procedural modeling and animation."))
    parser.add_argument("--version", action=_Version, nargs=0,
                        help="print scanamp's version and those of its core dependencies")
    parser.add_argument("--debug", action="store_true", help="show tracebacks and debug logs")
    parser.add_argument("-q", "--quiet", action="store_true", help="only warnings and errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    groups: dict[str, argparse._SubParsersAction] = {}
    group_help = {"capture": "render a virtual capture of a scene",
                  "reconstruct": "reconstruct a mesh from a capture",
                  "simulate": "run a procedural animation",
                  "procgen": "procedural modeling generators",
                  "calibrate": "calibrate a real camera or stereo pair from board photos",
                  "mesh": "mesh processing: clean a reconstruction"}
    for mod in _commands():
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
        dest = getattr(mod, "OUTPUT_DEST", "out")
        if any(a.dest == dest for a in p._actions):
            p.add_argument("--overwrite", action="store_true",
                           help="replace an output this command wrote before (never anything "
                                "else)")
        command = f"{group} {mod.NAME}" if group else mod.NAME
        p.set_defaults(_run=mod.run, _config_cls=config_cls, _module=mod, _command=command)
    return parser


def _input_paths(args: argparse.Namespace, dest: str) -> list[Path]:
    """Every existing path among the arguments other than the output: the inputs."""
    found = []
    for key, value in vars(args).items():
        if key in (dest, "command", "kind") or key.startswith("_"):  # not the subcommand
            continue
        for v in value if isinstance(value, (list, tuple)) else [value]:
            if isinstance(v, (str, Path)) and str(v) and os.path.exists(v):
                found.append(Path(v))
    return found


def _check_outputs(args: argparse.Namespace, config=None) -> tuple[Path, str] | None:
    """Refuse an output that would destroy something; the folder to mark as ours, if any."""
    from core.runs.outputs import check_output, check_output_file, read_manifest

    mod = args._module
    dest = getattr(mod, "OUTPUT_DEST", "out")
    out, kind = getattr(args, dest, None), getattr(mod, "OUTPUT", "dir")
    if out is None and kind != "file":
        return None
    inputs = _input_paths(args, dest)
    overwrite = bool(getattr(args, "overwrite", False))
    if kind == "file":
        if out is not None:
            check_output_file(out, inputs=inputs, overwrite=overwrite)
        companions = getattr(mod, "companions", None)
        for extra in (companions(args, config) if companions else []):
            extra = Path(extra)
            if extra.is_dir():
                check_output(extra, command=args._command, inputs=inputs, overwrite=overwrite)
            else:
                check_output_file(extra, inputs=inputs, overwrite=overwrite)
        return None
    out = Path(out)
    resumable = kind == "resume" and read_manifest(out) is not None
    check_output(out, command=args._command, inputs=inputs, overwrite=overwrite or resumable)
    return out, args._command


def _hold_output(args: argparse.Namespace, stack: contextlib.ExitStack) -> None:
    """Hold the output's lock (:func:`core.files.hold`) from its check to the command's end:
    a second process on the same output exits 2 and the first loses nothing."""
    from core.files import hold

    out = getattr(args, getattr(args._module, "OUTPUT_DEST", "out"), None)
    if isinstance(out, (str, Path)) and str(out):
        stack.enter_context(hold(out))


def _run(args: argparse.Namespace) -> int:
    from core import files
    from core.runs import outputs

    config = (config_from_args(args._config_cls, args) if args._config_cls is not None
              else None)
    with contextlib.ExitStack() as stack:
        _hold_output(args, stack)
        declared = _check_outputs(args, config)
        if declared is not None:
            stack.enter_context(outputs.writing(*declared, config))
        code = int((args._run(args, config) if config is not None else args._run(args)) or 0)
        if declared is not None and code == 0 and declared[0].is_dir() and \
                outputs.read_manifest(declared[0]) is None:
            files.write_declared(declared[0], declared[0])  # written in place, not atomically
    return code


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.DEBUG if args.debug else (logging.WARNING if args.quiet else logging.INFO)
    logging.basicConfig(level=level, format="%(message)s", stream=sys.stderr)
    for handler in logging.getLogger().handlers:
        handler.addFilter(_FinalPaths())
    if not args.debug:
        for noisy in ("numba", "matplotlib", "PIL", "distributed", "asyncio"):
            logging.getLogger(noisy).setLevel(logging.WARNING)
    if not args.quiet:
        from core import progress

        progress.enable(sys.stderr.isatty())
    try:
        return _run(args)
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
