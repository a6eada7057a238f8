"""The one usage-error type of every command-line entry point, and how it is reported.

Defined at the bottom layer so that `wildgen`, `unips`, `validate` and `orchestrate` CLIs share it without
importing each other: a CLI raises `UsageError` (or lets its library raise ValueError /
FileNotFoundError, or importing `scenes` raise `MissingDependencyError`), and its `main` turns that into one line
`error: ...` on stderr and a non-zero exit status with `report_error`, never a traceback.
"""
from __future__ import annotations

import os
import sys
from collections.abc import Callable, Sequence

EXIT_USAGE = 2
"""Exit status of a usage or input error (argparse's own)."""


class UsageError(Exception):
    """A usage or input error that a CLI reports as one line."""


class MissingDependencyError(ModuleNotFoundError):
    """This Python lacks packages every command needs (`scenes.dependencies`, raised by importing `scenes`); its
    message is one line naming them and the fix."""


class WorkingFolderGoneError(FileNotFoundError):
    """The process's current folder was deleted or moved away (raised by importing `scenes`): torch's MKL cannot
    even load there, so the one line says so before anything else does."""


INPUT_ERRORS: tuple[type[BaseException], ...] = (UsageError, ValueError, FileNotFoundError, MissingDependencyError)
"""Exceptions every CLI reports as one line with `report_error`."""


TRACEBACK = "Traceback (most recent call last):"


def _without_traceback(text: str) -> str:
    """The original message of an error that carries another process's traceback in its text (torch's DataLoader
    re-raises a worker's error as "Caught ValueError in DataLoader worker process 1.\nOriginal Traceback ...");
    other text as it is."""
    if TRACEBACK not in text:
        return text
    lines = text[text.rindex(TRACEBACK) + len(TRACEBACK):].splitlines()
    start = next((i for i, line in enumerate(lines) if line.strip() and not line.startswith(" ")), None)
    if start is None:
        return text
    kind, sep, message = "\n".join(lines[start:]).partition(": ")
    return message if sep and kind.replace(".", "").replace("_", "").isalnum() else kind + sep + message


def one_line(exc: BaseException) -> str:
    """The message of `exc` on one line (without a traceback another process put into it); a copy of a folder that
    failed (`shutil.Error`, a list of every file) by its first file; a full disk with what to do."""
    import errno
    import shutil

    if isinstance(exc, shutil.Error) and exc.args and isinstance(exc.args[0], list) and exc.args[0]:
        first = exc.args[0][0]
        src, dst, why = first if isinstance(first, tuple) and len(first) == 3 else ("?", "?", first)
        more = f" (and {len(exc.args[0]) - 1} more file(s))" if len(exc.args[0]) > 1 else ""
        text = f"could not copy {src!r} to {dst!r}{more}: {why}"
        full = "No space left on device" in str(why)
    else:
        text = _without_traceback(str(exc))
        full = isinstance(exc, OSError) and exc.errno == errno.ENOSPC
    if full:
        text += " (the disk it writes to is full: free space there, or write the output elsewhere)"
    return text.replace("\n", " ")


def stdout_gone() -> bool:
    """Whether standard output is a pipe nobody reads any more (poll says POLLERR on its writing end), so that a
    BrokenPipeError of another pipe (a step's) is still reported."""
    import select

    try:
        poller = select.poll()
        poller.register(sys.stdout.fileno(), select.POLLOUT)
        return any(event & select.POLLERR for _, event in poller.poll(0))
    except (OSError, ValueError, AttributeError):  # no fd (a test's capture) or no poll here
        return False


def hold_standard_streams() -> None:
    """Standard input, output and error open, and never failing on a character; called first by every entry point
    (`scenes.cli.supervise.run_supervised`, `Command.parse`). A descriptor 0-2 the caller closed (`2>&-`) is opened
    on /dev/null: else the first file or pipe the command opens takes its number, and a warning or a progress bar
    is written into it. A character the output's encoding lacks (PYTHONIOENCODING=ascii) is written escaped
    (`\\xe4`) rather than ending the command once its work is done."""
    for fd in (0, 1, 2):  # in order: os.open takes the lowest free number, the closed one
        try:
            os.fstat(fd)
        except OSError:
            null = os.open(os.devnull, os.O_RDWR)
            if null != fd:
                os.dup2(null, fd)
                os.close(null)
    for name, fd, mode in (("stdin", 0, "r"), ("stdout", 1, "w"), ("stderr", 2, "w")):
        if getattr(sys, name) is None:  # Python found the descriptor closed at its start
            setattr(sys, name, open(fd, mode, closefd=False, errors="backslashreplace"))
    for stream in (sys.stdout, sys.stderr):
        if getattr(stream, "errors", None) == "strict" and callable(getattr(stream, "reconfigure", None)):
            try:
                stream.reconfigure(errors="backslashreplace")
            except (ValueError, OSError):  # a stream that cannot change its mind (already detached)
                pass


def stdout_failed(exc: BaseException) -> int | None:
    """The exit status of a command whose standard output failed under it (`exc`, raised by a print), or None
    where `exc` is another's. Its reader gone (`| head -1`): 141 quietly, as SIGPIPE would end it; anything else
    (`> /dev/full`, a disk that filled): one line saying so, exit 2. Either way the output's descriptor is then
    /dev/null, so that the flush at exit has nowhere to fail."""
    import signal

    if not isinstance(exc, OSError) or getattr(exc, "filename", None) is not None:
        return None
    if isinstance(exc, BrokenPipeError):
        code = 128 + signal.SIGPIPE if stdout_gone() else None
    elif _raised_writing_stdout(exc):
        print(f"error: standard output: {one_line(exc)}; the command's messages could not be written (what it "
              "wrote in its folders is whole)", file=sys.stderr)
        code = EXIT_USAGE
    else:
        code = None
    if code is not None:
        os.dup2(os.open(os.devnull, os.O_WRONLY), 1)
    return code


def _raised_writing_stdout(exc: BaseException) -> bool:
    """Whether `exc` came out of a write to standard output: the statement it was raised in (the innermost one of
    its traceback) prints without `file=`, or writes or flushes `sys.stdout`. Read, not probed: a probe written
    to a working output would add a line to it, and one to a failing output would blame it for another's error."""
    import traceback

    frames = traceback.extract_tb(exc.__traceback__) if exc.__traceback__ is not None else []
    line = (frames[-1].line or "") if frames else ""
    return (line.startswith("print(") and "file=" not in line) or line.startswith(("sys.stdout.", "print()"))


def keep_stdout_failures_short(main: Callable[[], int]) -> int:
    """`main()`, where standard output failing under it (`stdout_failed`) ends the command without a traceback."""
    try:
        return main()
    except OSError as exc:
        if (code := stdout_failed(exc)) is None:
            raise
        return code


def report_error(exc: BaseException, code: int = EXIT_USAGE) -> int:
    """Print `error: <message>` (one line) on stderr and return the exit status `code`; standard output failing
    (`| head -1` went away) is said as `stdout_failed` says it."""
    if (failed := stdout_failed(exc)) is not None:
        return failed
    print(f"error: {one_line(exc)}", file=sys.stderr)
    return code


def check_text_arguments(argv: Sequence[str], positional: str) -> None:
    """A UsageError for an argument whose bytes are not text (Python keeps them as lone surrogates, which figures,
    pages, OpenEXR and OpenCV cannot take), named by its flag (`positional` when it follows none). Under a UTF-8
    file system encoding the name itself is not UTF-8 (`scenes.files.text_name_problem`: rename it); under another
    one (LANG=C with Python's UTF-8 mode off) the locale is what cannot read it."""
    from scenes.files import shown_name, text_name_problem

    for i, arg in enumerate(argv):
        flag, eq, value = arg.partition("=") if arg.startswith("--") else ("", "", arg)
        if not eq:
            flag, value = (argv[i - 1] if i and argv[i - 1].startswith("--") else positional), arg
        if (problem := text_name_problem(arg)) is None:
            long = max(value.split(os.sep), key=lambda part: len(os.fsencode(part)))
            if len(os.fsencode(long)) > 255 and not value.startswith("-") and "," not in value:  # no file has it
                raise UsageError(f"{flag}: {value[:60]!r}... holds a name of {len(os.fsencode(long))} bytes; expected "
                                 "names of at most 255 bytes (the file system's limit)")
            real = os.path.realpath(value) if value and not value.startswith("-") and os.path.lexists(value) else ""
            if (problem := text_name_problem(real)) is not None:  # a link to a folder named in another encoding
                raise UsageError(f"{flag}: {value!r} leads to {shown_name(real)!r}: {problem}")
            continue
        if sys.getfilesystemencoding().lower().replace("-", "") == "utf8":
            raise UsageError(f"{flag}: {shown_name(value)!r}: {text_name_problem(value)}")
        raise UsageError(f"{flag}: {shown_name(value)!r} holds characters this locale cannot read as text (LANG="
                         f"{os.environ.get('LANG', '')!r}, Python's UTF-8 mode off): run with PYTHONUTF8=1 or in a "
                         "UTF-8 locale (LANG=C.UTF-8)")
    tmp = os.environ.get("TMPDIR", "")
    if (problem := text_name_problem(tmp)) is not None:  # scratch folders are made under it
        raise UsageError(f"TMPDIR (environment): {shown_name(tmp)!r}: {problem}, or set TMPDIR to another folder")
