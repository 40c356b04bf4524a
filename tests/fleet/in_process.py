"""`fleet ARGV` run by its `main` in the test's own process: no interpreter to start, so a refusal or a check takes
milliseconds, not the seconds of a process's imports. Tests that need the process itself (exit on a signal, what is
left running) start one."""

import contextlib
import io
import sys

from fleet.cli import main


def fleet_in_process(argv: list[str]) -> tuple[int, str, str]:
    """The command's exit status and what it wrote to stdout and stderr."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse's own refusals, and sys.exit("message") as Python's exit says it
            code = exc.code
            if code is None:
                code = 0
            elif not isinstance(code, int):
                print(code, file=sys.stderr)
                code = 1
    return code, out.getvalue(), err.getvalue()
