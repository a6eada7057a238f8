"""`python -m wildgen.make`: render a PS-Wild-style photometric stereo dataset.

Example: python -m wildgen.make --lights near_area --objects 2 --images 4 --res 64 --spp 32 --out /tmp/x
"""
from __future__ import annotations

import logging
import os
import sys
import threading
import time
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Annotated, Literal

from scenes.checks import check_int
from scenes.cli.errors import UsageError, keep_stdout_failures_short, report_error
from scenes.cli.limits import check_memory as check_memory_bytes
from scenes.cli.limits import check_threads, gib
from scenes.cli.needs import Needs, value_of
from scenes.cli.options import REQUIRED, Command, arg, check_fields, option, optional_value
from scenes.cli.outputs import check_output_folder, check_replaceable, make_output_folder
from scenes.cli.progress import Progress, logs_above_progress
from scenes.folder.format import check_not_in_object_folder, entry_folder
from scenes.folder.shard_format import ENCODINGS
from wildgen.config import GenConfig
from wildgen.levels import LEVELS, apply_level, check_level_and_preset
from wildgen.light_families import ENVIRONMENT_FAMILIES
from wildgen.presets import apply_preset, preset_named


@dataclass
class MakeOptions:
    """The command line of wildgen.make: the dataset's configuration (`GenConfig`, recorded in its manifest)
    and how this run renders it."""

    out: Annotated[str, arg(metavar="DIR")] = REQUIRED
    """Output dataset directory."""
    res: int | None = None
    """Square resolution: sets both --width and --height."""
    gen: GenConfig = field(default_factory=GenConfig)
    """The dataset: what is rendered (every flag of `GenConfig`)."""
    threads: Annotated[int | None, arg(help_behavior_hint="(default: cores // workers, at least 1; with --ray: 1)")] = \
        option(None, minimum=1)
    """Dr.Jit threads per worker."""
    workers: Annotated[
        int | None, arg(help_behavior_hint="(default: one per core, at most one per object, 1 with a cuda variant)")
    ] = option(None, minimum=0)
    """Local worker processes (0: render in this process)."""
    ray: Annotated[str | None, optional_value("auto", "ADDRESS")] = None
    """Run one Ray task per object: no ADDRESS or 'auto' joins this machine's Ray cluster or starts a local one;
    else HOST:PORT or ray://... (needs pip install 'unips-toolkit[ray]')."""
    resume: bool = False
    """Continue the dataset in --out with the configuration of its manifest (flags given override it; --objects
    may grow). Re-running the same command resumes too."""
    overwrite: bool = False
    """Delete the dataset in --out (manifest and object folders) and start afresh."""
    max_retries: int = option(2, minimum=0)
    """Retries of an object after an exception or a dead worker before it is recorded as failed."""
    recycle_after: int = option(50, minimum=1)
    """Objects a worker process renders before a fresh process replaces it (bounds memory)."""
    quiet: bool = False
    """No progress bar."""
    shards: Annotated[str | None, arg(metavar="DIR")] = None
    """Also write the finished dataset as WebDataset shards into this folder (python -m wildgen.export, default
    shard size; checked before the render; an earlier export there is replaced when it was made from this dataset
    or with --overwrite)."""
    shard_encoding: Literal[ENCODINGS] = "files"
    """Encoding of --shards (wildgen.export --encoding): 'files' as they are, or 'decoded' (the reader's arrays,
    faster to train on)."""

    def validate(self) -> "MakeOptions":
        """The run's own options (the dataset's are `GenConfig.validate`'s)."""
        check_fields(self)
        if self.shard_encoding != "files" and not self.shards:
            raise UsageError(f"--shard-encoding: {self.shard_encoding!r} needs --shards (the folder to export to)")
        if self.res is not None:
            check_int(self.res, "--res", minimum=8, maximum=8192)
        if self.ray is not None:
            from wildgen.ray_engine import check_ray_address

            check_ray_address(self.ray)
        return self


COMMAND = Command(MakeOptions, prog="python -m wildgen.make", needs=(
    Needs("recycle_after", lambda c, _: c.workers != 0, "with worker processes (not --workers 0)"),
    Needs("shape_kinds", lambda c, _: value_of(c, "shapes") != "mesh", "with procedural shapes (not --shapes mesh)"),
    Needs("env_width", lambda c, _: bool(set(value_of(c, "lights")) & set(ENVIRONMENT_FAMILIES)),
          f"with a light family lit by the environment map ({', '.join(ENVIRONMENT_FAMILIES)})"),
    Needs("detail_strength", lambda c, _: bool(value_of(c, "detail")),
          "with procedural detail (--detail P above 0, or a --level that sets it)"),
    Needs("focal", lambda c, _: value_of(c, "camera") == "perspective", "with --camera perspective")),
                  needs_late=True,  # checked on the configuration that renders: after --preset, --level, --resume
                  description="Render a PS-Wild-style photometric stereo dataset with Mitsuba 3 (one <object>.data "
                              "folder per object).")


def options_from_args(argv: list[str] | None, given: set[str] = frozenset()) -> MakeOptions:
    """The options of a command line (not validated): the values of --preset on the dataset's fields whose flags
    are not in `given` (the flags on the command line), then --res on its width and height."""
    opts = COMMAND.parse(argv)
    check_level_and_preset(opts.gen, given)
    apply_preset(opts.gen, given)
    apply_level(opts.gen, given)
    if opts.res is not None:
        opts.gen.width = opts.gen.height = opts.res
    if opts.gen.assets:  # recorded in the manifest: a --resume from another folder finds them (sweep 33)
        opts.gen.assets = os.path.abspath(opts.gen.assets)
    return opts


# Flags that are part of GenConfig (with --resume, only those given explicitly override the manifest).
CONFIG_FLAGS = (*(f.name for f in fields(GenConfig)), "res")


def _explicit_flags(argv: list[str] | None) -> set[str]:
    """Names of the options given on the command line (not defaulted)."""
    return COMMAND.given(argv)


def _resume_config(opts: MakeOptions, explicit: set[str], manifest: dict) -> GenConfig:
    """The manifest's configuration, with the config flags given on this command line applied on top."""
    known = {f.name for f in fields(GenConfig)}
    cfg = GenConfig(**{k: v for k, v in manifest["config"].items() if k in known})
    given = opts.gen.to_dict()
    names = explicit & set(CONFIG_FLAGS)
    if "preset" in explicit and opts.gen.preset is not None:  # --preset given again: its values as if typed
        names |= set(preset_named(opts.gen.preset).overrides())
    if "level" in explicit and opts.gen.level is not None:  # --level given again: likewise
        names |= set(LEVELS[opts.gen.level].overrides()) - explicit
    for name in names:
        targets = ("width", "height") if name == "res" else (name,)
        for t in targets:
            setattr(cfg, t, given[t])
    try:
        return cfg.validate()
    except (ValueError, TypeError) as exc:  # a value the manifest recorded, not one typed: said as the manifest's
        field = str(exc).split(":", 1)[0].removeprefix("--").replace("-", "_")
        if field in names:
            raise
        raise ValueError(f"--resume: the configuration recorded in {str(Path(opts.out) / 'manifest.json')!r} is "
                         f"refused ({exc}); expected the manifest wildgen.make wrote: restore it, or start again with "
                         "--overwrite") from None


def _summary(entries: dict[int, dict], rendered: dict[str, int], plan, seconds: float, variant: str,
             how: str) -> tuple[str, int]:
    failed = sum(e.get("status") == "failed" for e in entries.values())
    rejected = plan.rejected + rendered.get("skipped", 0)
    detail = [f"{plan.complete} already complete"] * bool(plan.complete) + \
        [f"{rejected} rejected by the entropy rule or the ground-truth check"] * bool(rejected)
    line = (f"{rendered.get('done', 0)} done, {plan.complete + rejected} skipped, {failed} failed"
            + (f" ({', '.join(detail)})" if detail else ""))
    return f"{line} in {seconds:.1f} s [{variant}, {how}]", failed


def check_flags(opts: MakeOptions, explicit: set[str]) -> None:
    """Flag values and combinations that are refused before anything is read (ValueError)."""
    opts.validate()
    if opts.ray is not None and "workers" in explicit:
        raise ValueError("--workers: local workers and --ray are exclusive (Ray schedules by its CPUs)")
    if opts.resume and opts.overwrite:
        raise ValueError("--resume: cannot be combined with --overwrite")
    if opts.res is not None and explicit & {"width", "height"}:
        given = " and ".join(f"--{f}" for f in ("width", "height") if f in explicit)
        raise ValueError(f"--res: sets both sides; it cannot be combined with {given} (use --res R or --width W "
                         "--height H)")
    check_output_folder(opts.out)
    from scenes.cli.outputs import check_apart, check_no_holder_above
    check_no_holder_above(opts.out)  # before the render (the lock, taken later, checks again)
    check_not_in_object_folder(opts.out)  # (so is this one)

    check_apart(opts.out, {"--assets": opts.gen.assets})  # a dataset inside the assets is read as assets next time
    if opts.shards:  # the whole target, before the render: not found only when the dataset is done
        from wildgen.export import check_target, replaces_export

        check_target(opts.out, opts.shards, opts.overwrite or replaces_export(opts.shards, opts.out), "--shards",
                     "--out")
    if opts.ray is not None:
        from wildgen.parallel import RAY_INSTALL, ray_available

        if not ray_available():
            raise ValueError(f"--ray: Ray is not installed; {RAY_INSTALL}")
        from wildgen.ray_engine import probe_ray

        probe_ray(opts.ray)  # an address that does not answer, refused after a bounded wait


def resolve_run(args: MakeOptions, argv: list[str] | None, out: Path) -> tuple[GenConfig, str]:
    """The configuration to render (the manifest's one merged with the given flags when resuming) and the
    Mitsuba variant (set here; an existing dataset keeps its own unless one is asked for)."""
    from wildgen.dataset import load_manifest

    explicit = _explicit_flags(argv)

    manifest = None if args.overwrite else load_manifest(out)
    if args.resume:
        if manifest is None:
            raise FileNotFoundError(
                f"--resume: no manifest.json in {str(out)!r} to resume; run without --resume to start"
            )
        cfg = _resume_config(args, explicit, manifest)
    else:
        cfg = args.gen.validate()
    check_given(args, cfg, argv)
    if args.resume:  # (after check_given: a flag that would do nothing is said as such first)
        _check_resumable(manifest, cfg, explicit)
    check_config(args, cfg, resumed=args.resume and "objects" not in explicit)
    check_out(out, manifest if args.resume else None)
    from scenes.renderer.variant import choose_variant

    requested = cfg.variant or (manifest.get("variant") if manifest and "variant" not in explicit else None)
    variant = choose_variant(requested)
    if args.threads and args.workers == 0:
        import drjit as dr

        try:
            dr.set_thread_count(args.threads)
        except RuntimeError as exc:  # what the limits above did not foresee
            raise UsageError(f"--threads: cannot start {args.threads} Dr.Jit threads ({exc})") from None
    return cfg, variant


def _check_resumable(manifest: dict, cfg: GenConfig, explicit: set[str]) -> None:
    """A flag of --resume that changes what the manifest records is refused naming it (or the --preset that set it)."""
    from wildgen.dataset import config_differences

    diff = config_differences(manifest, cfg)
    if diff:
        key = diff[0]
        name = "res" if key in ("width", "height") else key
        flag = f"--{name.replace('_', '-')}" if name in explicit or "preset" not in explicit else "--preset"
        raise UsageError(f"{flag}: --resume continues the dataset in --out as its manifest records it ({key} "
                         f"{manifest['config'].get(key)!r}, here {getattr(cfg, key)!r}); leave the flag out to resume, "
                         "or start afresh with --overwrite")


def check_given(args: MakeOptions, cfg: GenConfig, argv: list[str] | None) -> None:
    """A flag given on the command line `argv` that the configuration to render (`cfg`, after the preset, the
    level or the resumed manifest) never reads is refused (not ignored)."""
    explicit = _explicit_flags(argv)
    try:
        COMMAND.check_needs(replace(args, gen=cfg), argv)
    except UsageError as exc:  # say where the setting it needs came from when the user did not type it
        source = [f"--{k} {getattr(cfg, k)}" for k in ("preset", "level") if k in explicit] + \
            ["the manifest of the run resumed"] * args.resume
        raise UsageError(f"{exc} (the flags not given here are those of {' and '.join(source)})" if source
                         else str(exc)) from None


def _check_threads(args: MakeOptions, cfg: GenConfig) -> None:
    """--threads x the local workers must be threads this machine can start."""
    from wildgen.parallel import default_workers

    workers = 1 if args.ray is not None or args.workers == 0 else (args.workers or default_workers(cfg.objects))
    check_threads(args.threads, "--threads", processes=workers)


def check_config(args: MakeOptions, cfg: GenConfig, resumed: bool = False) -> None:
    """The configuration to render against this machine and the assets, before anything is written: the asset
    folder (every asset decoded once, here: a bad file is named now, not retried in every object), the memory
    estimate and --threads. `resumed`: the configuration came from the manifest."""
    from wildgen.assets import AssetLibrary

    lib = AssetLibrary.scan(cfg.assets)  # fail early on a bad asset folder
    lib.check_drawn(cfg.assets, cfg.shapes, cfg.lights)
    check_memory(cfg, args.workers, args.ray is not None, resumed=resumed)
    _check_threads(args, cfg)
    lib.check()


def check_args(argv: list[str]) -> MakeOptions:
    """Everything `main` checks before it reads --out, on a command line, writing nothing: the flags, the
    dataset's configuration (`check_config`: assets decoded, memory, threads). What orchestrate checks of a
    wildgen.make step before running any step (`orchestrate.steps.check_step`)."""
    explicit = _explicit_flags(argv)
    args = options_from_args(argv, explicit)
    check_flags(args, explicit)
    if not args.resume:  # a resumed configuration is the manifest's, read when the step runs
        check_given(args, args.gen.validate(), argv)
        check_config(args, args.gen)
    return args


MANIFEST_BYTES_PER_OBJECT = 10_000
"""Bytes the parent process holds per object of the dataset (its manifest entry as a dict and as JSON text, the
plan), plus MANIFEST_BYTES_PER_IMAGE per image of it (checksums of the image files): measured 12.5 kB per
object of 2 images."""
MANIFEST_BYTES_PER_IMAGE = 400


def manifest_memory(cfg: GenConfig) -> int:
    """Bytes the manifest of `cfg` takes in the parent process (it holds every object's entry)."""
    return cfg.objects * (MANIFEST_BYTES_PER_OBJECT + MANIFEST_BYTES_PER_IMAGE * cfg.images)


def check_memory(cfg: GenConfig, workers: int | None, ray: bool, resumed: bool = False) -> None:
    """Refuse sizes this machine cannot hold: `GenConfig.memory_per_object` x concurrent workers, plus the
    manifest of `--objects` objects. `resumed`: the configuration came from the manifest (named in the error)."""
    from wildgen.parallel import default_workers

    per_object = cfg.memory_per_object()
    concurrent = 1 if ray or workers == 0 else min(workers or default_workers(cfg.objects), max(1, cfg.objects))
    manifest = manifest_memory(cfg)
    where = " (from manifest.json)" if resumed else ""
    if manifest > per_object * concurrent:
        check_memory_bytes(manifest + per_object * concurrent, f"--objects{where}",
                           f"the manifest of {cfg.objects} objects", "lower --objects or split the dataset")
    who = f" x {concurrent} workers" if concurrent > 1 else ""
    check_memory_bytes(per_object * concurrent + manifest, f"--res/--images/--spp/--gt-spp{where}",
                       f"one object at {cfg.width}x{cfg.height} px, {cfg.images} images, {cfg.spp} spp, "
                       f"{cfg.gt_spp} spp for the ground truth (about {gib(per_object)}{who})",
                       "lower --res, --images, --spp, --gt-spp or --workers")


def check_out(out: Path, manifest: dict | None = None) -> None:
    """--out must be a folder this process can create and write (checked, and created, before anything is
    written); with the `manifest` of a resumed run, its finished objects are kept as they are (a mount point
    there is no hindrance)."""
    make_output_folder(out)
    kept = [out / entry_folder(e) for e in (manifest or {}).get("objects", [])  # (load_manifest: a list)
            if isinstance(e, dict) and e.get("status") == "done"]
    check_replaceable(out, "--out", "wildgen.make", kept)  # a resumed or replaced dataset: nothing mounted inside


class _Progress:
    """The progress bar of a run: created when the plan is known, one tick per finished object."""

    def __init__(self, cfg: GenConfig, out: Path, quiet: bool):
        self.cfg, self.out, self.quiet = cfg, out, quiet
        self.rendered: dict[str, int] = {}
        self.plan = None
        self.bar = None
        self.left = 0

    def on_plan(self, plan) -> None:
        self.plan = plan
        # One line before the long work, also with --quiet (which only hides the bar): what and where.
        what = f"{self.cfg.width}x{self.cfg.height} px, {self.cfg.images} images, {self.cfg.spp} spp"
        if plan.resumed:
            print(
                f"resuming {self.out}: {plan.complete} complete, {plan.rejected} rejected, {len(plan.todo)} to render "
                f"({what})" + (f", {plan.leftovers} interrupted removed" if plan.leftovers else ""),
                flush=True,
            )
        else:
            print(f"rendering {len(plan.todo)} object(s) ({what}) into {self.out}", flush=True)
        self.bar = Progress("wildgen", "obj", total=self.cfg.objects, done=plan.complete + plan.rejected,
                            enabled=not self.quiet)
        self.left = len(plan.todo)

    def progress(self, entry: dict) -> None:
        self.rendered[entry["status"]] = self.rendered.get(entry["status"], 0) + 1
        self.left -= 1
        self.bar.advance(postfix={"done": self.rendered.get("done", 0), "failed": self.rendered.get("failed", 0),
                                  "left": self.left})

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _engine_description(used: dict, plan) -> str:
    return (f"{used['workers']} workers x {used['threads_per_worker']} Dr.Jit threads" if "workers" in used
            else f"ray, {used['cluster_cpus']} CPUs" if "cluster_cpus" in used
            else "nothing to render" if not plan.todo else "in process")


def main(argv: list[str] | None = None, state: dict | None = None) -> int:
    """The exit status; `state` gets what the run learned ("lost": its Ray cluster went away)."""
    import signal

    from wildgen import parallel
    from wildgen.engine_base import importing

    state = {} if state is None else state

    def on_signal(signum, frame):  # Ctrl-C, SIGTERM (schedulers), SIGHUP (a closed terminal): one clean stop
        state["signal"] = signum
        parallel.STOP_SIGNALS.append(signum)  # seen even when a native call turns the interrupt into an error
        if importing(frame):  # raised there it would abort the process: again in 50 ms, once the import is done
            signal.signal(signal.SIGALRM, lambda _s, f: on_signal(signum, f))
            return signal.setitimer(signal.ITIMER_REAL, 0.05)
        raise KeyboardInterrupt

    handled = [s for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)  # one the shell ignores (nohup) stays so
               if signal.getsignal(s) is not signal.SIG_IGN]
    main_thread = threading.current_thread() is threading.main_thread()
    previous = {s: signal.signal(s, on_signal) for s in handled} if main_thread else {}
    try:
        return _run(argv, state)
    except (Exception, KeyboardInterrupt) as exc:  # an interrupt may reach a library mid-import or mid-call and come
        if not isinstance(exc, KeyboardInterrupt) and "signal" not in state:  # out as another error (drjit's import
            raise  # turns it into a NameError): still the user's Ctrl-C, not a fault
        print("interrupted: finished objects are kept; re-run the same command to continue", file=sys.stderr)
        return 128 + state.get("signal", signal.SIGINT)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)  # a stop deferred past an import (on_signal) is not re-sent later
        for s, handler in previous.items():
            signal.signal(s, handler)
        parallel.STOP_SIGNALS.clear()


def _run(argv: list[str] | None, state: dict) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        explicit = _explicit_flags(argv)
        args = options_from_args(argv, explicit)
        out = Path(args.out)
        state["made"] = None if os.path.lexists(out) else out  # made by this run: a refusal leaves no empty folder
        check_flags(args, explicit)
        cfg, variant = resolve_run(args, argv, out)
    except (UsageError, ValueError, OSError) as exc:
        return _refused(exc, state)

    from contextlib import ExitStack

    from scenes.cli.outputs import output_lock

    with ExitStack() as held:
        if args.shards:  # held from the start: the export at the end is this run's (one writer per folder)
            try:
                held.enter_context(output_lock(args.shards, "--shards", inputs={"--out": str(out),
                                                                              "--assets": cfg.assets}))
            except (UsageError, ValueError, OSError) as exc:
                return _refused(exc, state)  # --out too, where this run made it
        return _render(args, cfg, variant, out, state)


def _refused(exc: BaseException, state: dict) -> int:
    """The one-line refusal, with --out removed where this run made it and left it empty."""
    if (made := state.get("made")) is not None and os.path.isdir(made) and not any(os.scandir(made)):
        os.rmdir(made)
    return report_error(exc)


def _render(args: MakeOptions, cfg, variant: str, out: Path, state: dict) -> int:
    """Render the dataset (then its shards, with --shards); the exit status."""
    from wildgen.dataset import make_dataset
    from wildgen.parallel import WorkersCannotStart, choose_engine
    from wildgen.ray_engine import ClusterLost

    engine = choose_engine(variant, ray=args.ray, workers=args.workers, threads=args.threads,
                           max_retries=args.max_retries, recycle_after=args.recycle_after)
    t0 = time.perf_counter()
    bar = _Progress(cfg, out, args.quiet)
    try:
        with logs_above_progress():  # warnings (retries, failures) print above the bar, not through it
            entries = make_dataset(cfg, out, variant, bar.progress, engine=engine, overwrite=args.overwrite,
                                   on_plan=bar.on_plan, extra={"run": engine.used})
    except ClusterLost as exc:  # a runtime loss, not a bad input: status 1 (the finished objects are recorded)
        bar.close()
        state["lost"] = True
        return report_error(exc, 1)
    except (ValueError, OSError, ImportError, WorkersCannotStart) as exc:
        bar.close()
        return _refused(exc, state)
    except KeyboardInterrupt:
        bar.close()
        raise
    bar.close()
    how = _engine_description(getattr(engine, "used", {}), bar.plan)
    line, failed = _summary(entries, bar.rendered, bar.plan, time.perf_counter() - t0, variant, how)
    print(f"dataset in {out}: <object>.data folders and manifest.json")
    print(line)
    bad = [e for e in sorted(entries.values(), key=lambda e: e["index"]) if e.get("status") == "failed"]
    for e in bad:
        print(f"failed {e['name']}: {e.get('error', '?')}", file=sys.stderr)
    if failed:
        first = f"{bad[0]['name']}: {bad[0].get('error', '?')}"
        full = " (the disk of --out is full: free space there)" if "No space left" in first else ""
        kept = "the others are in --out; " if failed < len(entries) else ""
        print(f"error: {failed} of {len(entries)} object(s) failed (first, {first}){full}; {kept}the same command "
              "again retries the failed ones", file=sys.stderr)
        return 1
    if entries and not any(e.get("status") == "done" for e in entries.values()):
        first = next(e for e in entries.values() if e.get("status") == "skipped")
        print(f"error: none of the {len(entries)} object(s) was written, all were rejected "
              f"(first: {first.get('reason')})", file=sys.stderr)
        return 1
    if args.shards:
        from wildgen.export import export_after_make

        return export_after_make(out, args.shards, args.shard_encoding, overwrite=args.overwrite)
    return 0



if __name__ == "__main__":
    ended: dict = {}
    code = keep_stdout_failures_short(lambda: main(state=ended))
    if code in (130, 143) or ended.get("lost"):
        # Everything is cleaned up and reported. An interrupt that arrived inside a native import leaves CPython's
        # "unhandled KeyboardInterrupt" flag set, which would turn this exit into a kill by SIGINT; after a lost
        # cluster, Ray's shutdown at exit waits for the head and may log a line of its own under ours.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)
