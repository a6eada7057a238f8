"""What the bench scripts' command lines share: the toolkit's tyro CLI (`scenes.cli.options.Command`), read the
same way, the default DiLiGenT folder and the record of the machine a result was measured on.

Each script (run as `python bench/NAME.py`, with the repository root put first on sys.path) declares its options
as a config dataclass and `COMMAND = Command(Options, prog="python bench/NAME.py", description=...)`; its `main`
reads the command line with `parse(COMMAND, argv)`. What the config alone cannot judge (files and folders on disk)
is checked in `main` before any work, each refusal one line `error: --flag: ...` and status 2 as well: the result
file (`claim_result`), a working folder (`check_work`), the inputs (`need_path`, `check_suites`, `check_diligent`,
`check_revision`), each inside `refusals()`; a list option given empty is refused by `check_given`.
"""
from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable, Sequence

from scenes.cli.errors import INPUT_ERRORS, UsageError, report_error
from scenes.cli.options import Command, check_fields

ROOT = Path(__file__).resolve().parents[1]
"""The repository root."""
DILIGENT = ROOT.parent / "shared" / "data" / "diligent"
"""Where the DiLiGenT objects (ballPNG/, catPNG/, ...) lie next to the checkout."""
MIN_RES = 8
"""The smallest image side a bench renders or writes: the generator's (`wildgen.config.GenConfig` --width and
--height: an object needs pixels to be kept)."""


def check_given(cfg: Any, *names: str) -> None:
    """A UsageError naming the flag of the first of the list options `names` given empty (`--sizes ''`): each is
    what the bench measures, one or more values."""
    import dataclasses

    from scenes.cli.options import flag_name

    for f in dataclasses.fields(cfg):
        if f.name in names and not getattr(cfg, f.name):
            raise UsageError(f"{flag_name(type(cfg), f)}: got '', expected one or more values, comma-separated")


def parse(command: Command, argv: Sequence[str] | None = None) -> Any:
    """The checked config of `argv` (sys.argv[1:] when None): its `validate()` where the config has one, else
    `check_fields`. A bad command line prints one line `error: ...` on stderr and exits with status 2, as
    argparse did; `--help` prints the help and exits 0."""
    try:
        cfg = command.parse(argv)
        cfg = cfg.validate() if hasattr(cfg, "validate") else check_fields(cfg)
    except INPUT_ERRORS as exc:
        raise SystemExit(report_error(exc)) from None
    return absolute_paths(cfg)


def absolute_paths(cfg: Any) -> Any:
    """`cfg` with every path it holds made absolute against the folder the bench was started in (a Path, a list of
    Paths, a text option whose metavar names a DIR or FILE): a bench runs steps with the repository as their working
    folder, where a relative --work would land inside the repository."""
    import dataclasses
    import typing

    hints = typing.get_type_hints(type(cfg), include_extras=True)
    for f in dataclasses.fields(cfg):
        value = getattr(cfg, f.name)
        metavars = [getattr(m, "metavar", None) or "" for m in getattr(hints.get(f.name), "__metadata__", ())]
        if isinstance(value, Path):
            setattr(cfg, f.name, value.absolute())
        elif isinstance(value, list) and value and all(isinstance(v, Path) for v in value):
            setattr(cfg, f.name, [v.absolute() for v in value])
        elif isinstance(value, str) and value and any(m in ("DIR", "FILE") for m in metavars):
            setattr(cfg, f.name, os.path.abspath(value))
    return cfg


@contextmanager
def refusals() -> Iterator[None]:
    """A check in `main` before any work: a UsageError, ValueError or FileNotFoundError raised in the block is one
    line `error: ...` on stderr and status 2, as `parse` reports a bad command line."""
    try:
        yield
    except INPUT_ERRORS as exc:
        raise SystemExit(report_error(exc)) from None


def claim_result(path: str | os.PathLike | None, keys: Sequence[str], owner: Command | str,
                 flag: str = "--out", inputs: dict[str, str | os.PathLike | None] | None = None) -> Path | None:
    """The result file `path` of a bench (None: no result file asked for), claimed before any work; its folder is
    created. Refused in one line naming `flag` (status 2): an existing folder, a link or anything but a plain file,
    a folder above it that is a file or not writable, and an existing file that is not an earlier result of this
    bench, i.e. not a JSON object holding every key of `keys` (the keys each of its results writes): a bench never
    replaces a file it did not write. An earlier result is replaced (atomically, by `scenes.files.write_json`)."""
    if path is None:
        return None
    from scenes.cli.outputs import check_apart, check_no_holder_above, holds_keys, make_output_folder

    owner = owner.prog if isinstance(owner, Command) else owner
    text, target = str(path), Path(path)
    with refusals():
        if not text.strip():
            raise UsageError(f"{flag}: got {text!r}, expected a file name")
        if target.is_dir():
            raise UsageError(f"{flag}: got {text!r}, expected a file: it is an existing folder (name a file in it, "
                             f"e.g. {str(target / 'result.json')!r})")
        if target.is_symlink() or (os.path.lexists(target) and not target.is_file()):
            kind = "a link" if target.is_symlink() else "not a plain file"
            raise UsageError(f"{flag}: {text!r} is {kind}; it is never replaced: move it away or use another {flag}")
        if target.is_file() and (other := _written_by(target)) not in (None, owner):
            raise UsageError(f"{flag}: {text!r} was written by {other}, not {owner}; it is never replaced: move it "
                             f"away or use another {flag}")
        if target.is_file() and not holds_keys(target, tuple(keys)):
            why = unreadable(target) or f"it is not a JSON object with the keys {', '.join(keys)} of its results"
            raise UsageError(f"{flag}: {text!r} was not written by {owner} ({why}); it is never replaced: move it "
                             f"away or use another {flag}")
        check_apart(target, dict(inputs or {}), flag)  # never inside what the bench reads (`inputs`: flag -> path)
        check_no_holder_above(target, flag)  # nor inside a folder another run writes
        make_output_folder(target.parent, flag)
    _CLAIMED[target.absolute()] = (_file_state(target), flag, owner)
    return target


def unreadable(path: Path) -> str | None:
    """Why the JSON file `path` cannot be read (not UTF-8 text, not JSON), None when it can."""
    from scenes.files import read_json

    try:
        read_json(path)
    except (OSError, ValueError, RecursionError) as exc:
        return f"it cannot be read as JSON: {str(exc)[:200]}"
    return None


def _written_by(path: Path) -> str | None:
    """The bench a result file says wrote it (its `WRITTEN_BY` key, which `write_result` adds), None when it says
    none (a result written before the key, or no result at all)."""
    from scenes.files import read_json

    try:
        value = read_json(path)
    except (OSError, ValueError, RecursionError):
        return None
    return str(value.get(WRITTEN_BY)) if isinstance(value, dict) and WRITTEN_BY in value else None


WRITTEN_BY = "written_by"
"""The key of every bench result that names the bench that wrote it (`write_result`): a result of another bench with
the same keys (most hold `rows`) is never replaced by this one."""

_CLAIMED: dict[Path, tuple[tuple[int, int, int] | None, str, str]] = {}
"""Each result file claimed (`claim_result`) or written (`write_result`) by this bench: its state then, its flag
and the bench that claimed it."""


def _file_state(path: Path) -> tuple[int, int, int] | None:
    """What tells one version of the file `path` from another (inode, change time, size); None: no file there."""
    try:
        st = os.lstat(path)
    except OSError:
        return None
    return st.st_ino, st.st_ctime_ns, st.st_size


def write_result(path: str | os.PathLike, obj: Any = None, *, text: str | None = None, **json_options: Any) -> Path:
    """Write a bench's result `obj` (`scenes.files.write_json` with `json_options`), or its `text`, to the file
    `path` that `claim_result` claimed, atomically. A file there that changed since the claim or this bench's last
    write (a user saved one during a run of hours) is never replaced: the result goes to a free name beside it and
    the run ends in one line naming both (status 2). A result object names the bench that claimed it (`WRITTEN_BY`).
    """
    from scenes.files import atomic_write_text, json_text

    target = Path(path)
    claimed, flag, owner = _CLAIMED.get(target.absolute(), (_file_state(target), "--out", ""))
    if isinstance(obj, dict) and owner:
        obj = {WRITTEN_BY: owner, **{k: v for k, v in obj.items() if k != WRITTEN_BY}}
    body = text if text is not None else json_text(obj, **json_options)
    if _file_state(target) != claimed:
        n = 1
        while os.path.lexists(aside := target.with_name(f"{target.stem}.result-{n}{target.suffix}")):
            n += 1
        atomic_write_text(aside, body)
        raise UsageError(f"{flag}: {str(path)!r} changed during the run (another program wrote it); it is never "
                         f"replaced: the result was written to {str(aside)!r}")
    atomic_write_text(target, body)
    _CLAIMED[target.absolute()] = (_file_state(target), flag, owner)
    return target


def check_work(path: str | os.PathLike | None, flag: str = "--work",
               inputs: dict[str, str | os.PathLike | None] | None = None) -> None:
    """A working folder (None: a temporary one), before any work: refused in one line naming `flag` when it is an
    existing file, lies under a file, cannot be written, or is, lies inside or leads into one of the bench's
    `inputs` (flag -> path: a split or a render written into the asset library). Creates nothing."""
    if path is None:
        return
    from scenes.cli.outputs import check_apart, check_no_holder_above, check_not_being_written, check_output_folder

    with refusals():
        check_output_folder(path, flag)
        check_not_being_written(path, flag)  # a folder wildgen.make (or another bench's step) is writing now
        check_no_holder_above(path, flag)  # inside a folder another run writes, the two runs' files would mix
        check_apart(path, {k: v for k, v in (inputs or {}).items() if v not in (None, "none")}, flag)


def need_path(path: str | os.PathLike, flag: str, what: str, folder: bool = True) -> Path:
    """An input of a bench that must exist (a folder, or a file with `folder` False), before any work: refused in
    one line naming `flag`, the path and `what` was expected."""
    target = Path(path)
    with refusals():
        if not (target.is_dir() if folder else target.is_file()):
            state = ("does not exist" if not os.path.lexists(target) else "is a file" if target.is_file() else
                     "is a folder" if target.is_dir() else "is neither a file nor a folder (a pipe, a device, a socket "
                     "or a broken link)")
            raise UsageError(f"{flag}: {str(path)!r} {state}; expected {what}")
    return target


def check_suites(suites: Sequence[str | os.PathLike], flag: str = "--suite") -> None:
    """Rendered datasets (`wildgen.make` folders of `*.data` object folders), before any work: one that is missing or
    holds no object folder is refused in one line naming `flag` and the path."""
    what = "a wildgen.make dataset (a folder of *.data object folders)"
    for suite in suites:
        need_path(suite, flag, what)
        if not any(p.is_dir() for p in Path(suite).glob("*.data")):
            with refusals():
                raise UsageError(f"{flag}: {str(suite)!r} holds no *.data object folder; expected {what}")


def check_revision(rev: str, flag: str = "--baseline") -> None:
    """A git revision of this repository (a bench compares this tree with it), before any work: anything that is
    not a commit here is refused in one line naming `flag`."""
    import subprocess

    with refusals():
        known = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--verify", "--quiet", f"{rev}^{{commit}}"],
                               capture_output=True, text=True)
        if known.returncode != 0:
            raise UsageError(f"{flag}: got {rev!r}, expected a commit of this repository")


DILIGENT_OBJECT = "a DiLiGenT object folder (001.png..., light_directions.txt, mask.png, Normal_gt.png or .mat)"


def check_diligent(data: str | os.PathLike, names: Sequence[str], flag: str = "--data") -> list[Path]:
    """The DiLiGenT object folders `data`/NAME of `names` (e.g. catPNG), each checked before any work: refused in
    one line naming `flag` and the folder that is missing or is not a DiLiGenT object with its mask and ground
    truth."""
    from scenes.folder.layouts import detect_layout

    folders = []
    with refusals():
        for name in names:
            if not name or name in (".", "..") or "/" in name or os.sep in name or list(names).count(name) > 1:
                raise UsageError(f"--objects: got {name!r}, expected the names of distinct object folders directly "
                                 f"under {flag} (e.g. ballPNG), each once: the work and result rows are named after "
                                 "them")
            folder = Path(data) / name
            near = name[:-3] if name.endswith("PNGPNG") else None if name.endswith("PNG") else name + "PNG"
            if not folder.is_dir() and near and (Path(data) / near).is_dir():  # 'ballPNG' where 'ball' is asked
                raise UsageError(f"--objects: {str(data)!r} holds no folder {name} but one named {near}: check the "
                                 "form --objects takes (see --help)")
            if not folder.is_dir():
                raise UsageError(f"{flag}: {str(folder)!r} does not exist: {str(data)!r} holds no object {name}; "
                                 f"expected {DILIGENT_OBJECT}")
            truth = (folder / "Normal_gt.png").is_file() or (folder / "Normal_gt.mat").is_file()
            if detect_layout(folder) != "diligent" or not (folder / "mask.png").is_file() or not truth:
                raise UsageError(f"{flag}: {str(folder)!r} is not {DILIGENT_OBJECT}")
            folders.append(folder)
    return folders


STOPPED = "interrupted: the bench's temporary files are removed and its results not written; run it again"
"""The one line of a stopped bench."""
GRACE_S = 10.0
"""Seconds a stopped bench has to end through its own `finally` blocks before it is ended outright."""


def run_main(main: Callable[[], int]) -> int:
    """A bench script's `main()`, run as the toolkit's commands are (`scenes.cli.supervise.run_supervised`): the
    work in a child process of its own session, which a stop (Ctrl-C, SIGTERM, SIGHUP) ends whole, with one line
    (`STOPPED`) and status 128 + the signal, whatever a render in progress does with the interrupt (Mitsuba's
    render installs a SIGINT handler of its own that may swallow it: the bench rendered on). Inside the child,
    `_run_here`."""
    import sys

    from scenes.cli.supervise import run_supervised

    return run_supervised(f"bench-{Path(sys.argv[0]).stem}", lambda: _run_here(main), interrupted=STOPPED,
                          command=[sys.executable, sys.argv[0]])


def _run_here(main: Callable[[], int]) -> int:
    """A bench script's `main()`, stopped cleanly: Ctrl-C, SIGTERM and SIGHUP end it with one line and status 128 +
    the signal, not a traceback, and nothing left in TMPDIR: the bench runs with a TMPDIR of its own (its steps too),
    removed however it ends. The stop reaches the bench as KeyboardInterrupt, through its `finally` blocks; an
    interrupt a native call swallows (Dr.Jit turns one into an error the render loop records and goes on) ends it
    outright after GRACE_S. A signal the shell ignores (nohup, a background job) stays ignored. A step that fails
    (CalledProcessError) is one line too."""
    import os
    import shutil
    import signal
    import subprocess
    import sys
    import tempfile
    import threading

    from scenes.cli.supervise import scratch_tmpdir

    got: dict[str, int] = {}
    env = scratch_tmpdir("bench")  # {} where TMPDIR is unwritable: the bench's own writes say so
    os.environ.update(env)
    scratch = tempfile.tempdir = env.get("TMPDIR")

    def end_now(signum: int) -> None:
        print(STOPPED, file=sys.stderr, flush=True)
        if scratch:
            shutil.rmtree(scratch, ignore_errors=True)
        os._exit(128 + signum)

    def on_stop(signum, _frame) -> None:
        if "signal" not in got:
            got["signal"] = signum
            timer = threading.Timer(GRACE_S, end_now, (signum,))
            timer.daemon = True  # a bench that ends in time is not held back by it
            timer.start()
        raise KeyboardInterrupt

    for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        if signal.getsignal(s) is not signal.SIG_IGN:
            signal.signal(s, on_stop)
    try:
        code = main()
    except subprocess.CalledProcessError as exc:  # a step the bench ran failed: its own output said why
        step = " ".join(map(str, exc.cmd[1:4])) if isinstance(exc.cmd, list) else str(exc.cmd)
        print(f"error: step {step} ... failed with status {exc.returncode} (its output above says why)",
              file=sys.stderr)
        code = 1
    except INPUT_ERRORS as exc:  # a toolkit step refused its input (a held folder, a bad file): its one line
        code = report_error(exc)
    except KeyboardInterrupt:
        code = None
    finally:
        if scratch:
            shutil.rmtree(scratch, ignore_errors=True)
    if "signal" in got:  # stopped, even where the interrupt was swallowed and main() returned
        print(STOPPED, file=sys.stderr)
        return 128 + got["signal"]
    return 130 if code is None else code


def machine() -> dict:
    """The `machine` record of a bench's output: the machine's cores and platform."""
    import os
    import platform

    return {"cpus": os.cpu_count(), "platform": platform.platform()}


def clipping_scale(images, mask, share: float) -> float:
    """The one factor for every image that makes `share` of the object's values (all images, `mask`) clip: a
    user's exposure, bright but not blown."""
    import numpy as np

    return 1.0 / float(np.quantile(images[:, mask], 1.0 - share))


def write_jpeg_photos(folder: Path, images, scale: float) -> None:
    """Linear images (K, H, W, 3) times `scale` as 8-bit sRGB JPEG files `IMG_0001.jpg` ... (quality 95) in the
    existing `folder`, as a camera writes them."""
    import cv2
    import numpy as np

    from scenes.colors import linear_to_srgb

    for i, img in enumerate(images):
        codes = np.round(np.clip(linear_to_srgb(np.clip(img * scale, 0, 1)), 0, 1) * 255).astype(np.uint8)
        cv2.imwrite(str(folder / f"IMG_{i + 1:04d}.jpg"), codes[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, 95])
