"""The `modb` command line as the tests run it: as a user's process by default, or in this process
(`process=False`: its `main()`, with what it prints captured).

In process saves each call the interpreter's start and numpy, scipy and scikit-learn's imports (1 to
1.7 s a call), but is not the default yet: with every call in process, a clean-clone run failed
test_avatar_web's two-connection test (a statement timeout) where the same tree with processes
passed; until that is understood, a test opts in. The result is the same
`subprocess.CompletedProcess` either way: an exception the command does not handle becomes exit
status 1 with its traceback in stderr, as Python's own exit would make it. Standard output and error
are process-wide, so a call from another thread than the main one runs as a process."""

from __future__ import annotations

import contextlib
import io
import subprocess
import sys
import threading
import traceback

from modb.cli.main import main


def run_modb(dsn: str, *args: str, process: bool = True) -> subprocess.CompletedProcess:
    """`modb --dsn DSN ARGS...`: its exit status, standard output and standard error (text)."""
    argv = ["--dsn", dsn, *map(str, args)]
    if process or threading.current_thread() is not threading.main_thread():
        return subprocess.run(
            [sys.executable, "-m", "modb.cli", *argv], capture_output=True, text=True
        )
    return _in_process(argv)


def run_modb_here(dsn: str, *args: str) -> subprocess.CompletedProcess:
    """run_modb in this process (process=False): for tests whose subject is not the process."""
    return run_modb(dsn, *args, process=False)


def _captured() -> io.TextIOWrapper:
    """A text stream with a `.buffer`, as sys.stdout has (`--out -` writes bytes to it)."""
    return io.TextIOWrapper(io.BytesIO(), encoding="utf-8", errors="replace", write_through=True)


def _in_process(argv: list[str]) -> subprocess.CompletedProcess:
    out, err = _captured(), _captured()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as e:  # argparse's refusals and --help, a command's sys.exit
            if e.code is None or isinstance(e.code, int):
                code = e.code or 0
            else:
                print(e.code, file=sys.stderr)
                code = 1
        except KeyboardInterrupt:
            raise
        except BaseException:  # as the interpreter reports an unhandled exception
            traceback.print_exc()
            code = 1
    texts = [stream.buffer.getvalue().decode("utf-8", "replace") for stream in (out, err)]
    return subprocess.CompletedProcess(["modb", *argv], code, *texts)
