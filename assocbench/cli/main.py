"""``assocbench`` command line: one small module per command; known errors exit 2, no traceback."""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
from contextlib import contextmanager

from ..errors import UserError
from ..harness.sandbox import TaskFailed
from . import check_cmd, export_cmd, frame_cmd, leaderboard_cmd, list_cmd, render_cmd, report_cmd, run_cmd, train_cmd

COMMANDS = (run_cmd, leaderboard_cmd, report_cmd, check_cmd, list_cmd, frame_cmd, render_cmd, export_cmd, train_cmd)


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, exit 2 (argparse's own convention too)
        self.exit(2, f"assocbench: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="assocbench", description="Benchmark for data association in SLAM and tracking.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    parser.commands = {}
    for module in COMMANDS:
        p = sub.add_parser(module.NAME, help=module.HELP, description=module.HELP)
        module.add_arguments(p)
        p.set_defaults(handler=module.main)
        parser.commands[module.NAME] = p
    return parser


class _Terminated(KeyboardInterrupt):
    """SIGTERM (what CI timeouts send first), raised like Ctrl-C so that the same cleanup runs:
    workers killed, finished results kept."""


def _on_sigterm(signum, frame) -> None:
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # a second SIGTERM ends the process outright
    raise _Terminated()


@contextmanager
def _sigterm_as_interrupt():
    if threading.current_thread() is not threading.main_thread():  # only the main thread may
        yield
        return
    previous = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:   # reported by the command's own parser, so the hint names the command
        parser.commands[args.command].error(f"unrecognized arguments: {' '.join(extra)}")
    try:
        with _sigterm_as_interrupt():
            code = int(args.handler(args) or 0)
            sys.stdout.flush()   # here, not at exit: a reader that left is handled below
            return code
    except UserError as exc:
        print(f"assocbench: error: {exc}", file=sys.stderr)
        return 2
    except TaskFailed as exc:   # our own code failed outside any method call; the other runs are kept
        print(f"assocbench: error: {exc}; finished runs are kept and a rerun resumes", file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:
        what = "terminated" if isinstance(exc, _Terminated) else "interrupted"
        kept = "; finished runs are kept and a rerun resumes" if args.command == "leaderboard" else ""
        print(f"assocbench: {what}{kept}", file=sys.stderr)
        return 143 if isinstance(exc, _Terminated) else 130
    except BrokenPipeError:   # `assocbench list | head -1`: the reader left, nothing to say to it
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())   # the exit flush cannot fail
        return 141   # the shell's code for a writer stopped by SIGPIPE (128 + 13)


if __name__ == "__main__":
    sys.exit(main())
