"""What the bench scripts' command lines share: the toolkit's tyro CLI (`scenes.cli.options.Command`), read the
same way, the default DiLiGenT folder and the record of the machine a result was measured on.

Each script (run as `python bench/NAME.py`, with the repository root put first on sys.path) declares its options
as a config dataclass and `COMMAND = Command(Options, prog="python bench/NAME.py", description=...)`; its `main`
reads the command line with `parse(COMMAND, argv)`.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Sequence

from scenes.cli.errors import INPUT_ERRORS, report_error
from scenes.cli.options import Command, check_fields

ROOT = Path(__file__).resolve().parents[1]
"""The repository root."""
DILIGENT = ROOT.parent / "shared" / "data" / "diligent"
"""Where the DiLiGenT objects (ballPNG/, catPNG/, ...) lie next to the checkout."""


def parse(command: Command, argv: Sequence[str] | None = None) -> Any:
    """The checked config of `argv` (sys.argv[1:] when None): its `validate()` where the config has one, else
    `check_fields`. A bad command line prints one line `error: ...` on stderr and exits with status 2, as
    argparse did; `--help` prints the help and exits 0."""
    try:
        cfg = command.parse(argv)
        return cfg.validate() if hasattr(cfg, "validate") else check_fields(cfg)
    except INPUT_ERRORS as exc:
        raise SystemExit(report_error(exc)) from None


STOPPED = "interrupted: the bench's temporary files are removed and its results not written; run it again"
"""The one line of a stopped bench."""
GRACE_S = 10.0
"""Seconds a stopped bench has to end through its own `finally` blocks before it is ended outright."""


def run_main(main: Callable[[], int]) -> int:
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
