"""Ship a GPU session's weights, or not, by rule (issue 41): score them here, on the CPU, against the shipped ones.

    python -m orchestrate.ship --candidate OUT --val WORK/val128 [--diligent ../shared/data/diligent] [--threads 2]

`--candidate` is the folder a GPU session brought back (`orchestrate.gpu_session --out`): its
run/final.safetensors, or run/last.pt when the session was cut short; its model_card.json and summary.json
(hardware, minutes, steps, data) when present. The candidate must be the shipped model's architecture (same
registered name and configuration) and, as a .safetensors file, under 16 MiB; otherwise one line, exit 2,
nothing written.

Both the candidate and the shipped weights are scored on the fixed validation set `--val` (the recipe's val128:
`orchestrate.train_recipe`'s seed 4000, held-out assets) with the probes all images, one image and mask only
(`orchestrate.train_recipe._val_probes`, as unips.train validates), and on DiLiGenT ball and cat when
`--diligent` holds them (all images, the first image, mask only; `orchestrate.benchmark`'s error). The candidate
is shipped (copied to the registry's pretrained entry, `orchestrate.train_recipe.install_weights`) only when its
fixed-validation mean over all images is lower than the shipped weights'; the run is recorded in the model
card's lineage either way (hardware, minutes, steps, data, figures, shipped or not).
"""
from __future__ import annotations

import json
import os
import platform
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

from scenes.cli.errors import INPUT_ERRORS, UsageError, report_error
from scenes.cli.options import REQUIRED, Command, arg, check_fields, option
from scenes.files import read_json

REPO = Path(__file__).resolve().parents[1]
DILIGENT = REPO.parent / "shared" / "data" / "diligent"
SHIP_LIMIT = 16 * 2**20
"""Bytes a shipped weights file may have."""
DILIGENT_OBJECTS = ("ball", "cat")
PROBES = ("all", "one", "mask")


@dataclass
class ShipOptions:
    """The command line of orchestrate.ship."""

    candidate: str = REQUIRED
    """Folder a GPU session brought back: run/final.safetensors (or run/last.pt), model_card.json, summary.json."""
    val: str = REQUIRED
    """The fixed validation set (orchestrate.train_recipe's WORK/val128)."""
    diligent: Annotated[str | None, arg(help_behavior_hint="(default: ../shared/data/diligent when it exists)")] = None
    """DiLiGenT folder; its ball and cat are scored too (`none`: skip)."""
    threads: int = option(2, minimum=1)
    """Torch threads."""

    def validate(self) -> "ShipOptions":
        check_fields(self)
        if not Path(self.val).is_dir():
            raise UsageError(f"--val: {self.val!r} is not a folder (expected the fixed validation set, "
                             "orchestrate.train_recipe's WORK/val128)")
        if self.diligent is None and DILIGENT.is_dir():
            self.diligent = str(DILIGENT)
        if self.diligent not in (None, "none") and not Path(self.diligent).is_dir():
            raise UsageError(f"--diligent: {self.diligent!r} is not a folder (expected DiLiGenT's folder, or 'none')")
        return self


def candidate_weights(folder: Path, scratch: Path) -> tuple[Path, str]:
    """The candidate's weights as a .safetensors file (a last.pt is converted into `scratch`) and its model name,
    checked: present, the shipped architecture, under `SHIP_LIMIT`. UsageError (one line) otherwise."""
    from orchestrate.relay import check_architecture
    from unips.models import load_model, pretrained_entry
    from unips.models.builder import save_checkpoint

    run = folder / "run"
    found = next((p for p in (run / "final.safetensors", run / "last.pt") if os.path.lexists(p)), None)
    if found is None:
        raise UsageError(f"--candidate: {str(folder)!r} holds neither run/final.safetensors nor run/last.pt (expected "
                         "the folder orchestrate.gpu_session --out brought back)")
    try:
        model, meta = load_model(found)
    except Exception as exc:  # any unreadable file is one line
        raise UsageError(f"--candidate: {str(found)!r} is not a weights file this package reads "
                         f"({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})") from None
    name = meta.get("model_name")
    try:
        pretrained_entry(name)
    except ValueError as exc:
        raise UsageError(
            f"--candidate: {str(found)!r} holds {name!r}, which has no shipped-weights entry ({exc})"
        ) from None
    check_architecture(found, name, meta.get("config"), "--candidate")
    if found.suffix != ".safetensors":
        found = save_checkpoint(scratch / "candidate.safetensors", model, extra=meta.get("extra"))
    size = found.stat().st_size
    if size > SHIP_LIMIT:
        raise UsageError(f"--candidate: {str(found)!r} is {size} bytes, over the {SHIP_LIMIT} bytes (16 MiB) shipped "
                         "weights may have (expected a smaller model)")
    return found, name


def diligent_scores(weights: Path, root: Path | None, threads: int) -> dict:
    """{object: {probe: mean angular error}} of `weights` on DiLiGenT's ball and cat (those present in `root`)."""
    import torch

    from orchestrate.benchmark import _mae, probe_inputs
    from scenes.folder.layouts import diligent_folders
    from unips.data import load_object
    from unips.inference import load_network, predict_object

    if root is None:
        return {}
    torch.set_num_threads(threads)
    net = load_network(weights)
    out = {}
    for folder in diligent_folders(root):
        name = folder.name[:-3]
        if name not in DILIGENT_OBJECTS:
            continue
        obj = load_object(folder)
        out[name] = {p: round(_mae(predict_object(probe_inputs(obj, p), "model", net=net), obj.normals, obj.mask), 2)
                     for p in PROBES}
    return out


def score(weights: Path, val: Path, diligent: Path | None, threads: int) -> dict:
    """Fixed-validation mean (all images), its probes and gain, and the DiLiGenT figures of `weights`."""
    from orchestrate.train_recipe import _val_probes

    res = _val_probes(weights, val, threads, "--val")
    return {"mean": res["mean"], "gain": res["gain"], "probes": {p: round(res["probes"][p], 2) for p in PROBES
                                                               if p in res["probes"]},
            "families": res.get("families", {}), "diligent": diligent_scores(weights, diligent, threads), "_res": res}


def _read(path: Path) -> dict:
    """A record the session brought back (model_card.json, summary.json): {} when absent; a file that is not a
    JSON object is a UsageError naming it (checked before any evaluation: `check_records`)."""
    from scenes.files import not_a_file

    if not os.path.lexists(path):
        return {}
    if why := not_a_file(path):
        raise UsageError(f"--candidate: {str(path)!r} {why}")
    try:
        record = read_json(path)
    except RecursionError:
        raise UsageError(f"--candidate: {str(path)!r} is nested too deeply to be a session's record") from None
    except (OSError, ValueError) as exc:
        raise UsageError(f"--candidate: {str(path)!r} cannot be read as JSON ({str(exc)[:120]}); expected the file "
                         "orchestrate.gpu_session wrote") from None
    if not isinstance(record, dict):
        raise UsageError(f"--candidate: {str(path)!r} holds a JSON {type(record).__name__}, expected the object "
                         "orchestrate.gpu_session writes")
    return record


RECORD_FIELDS = {"model_card.json": {"train_minutes": "number", "steps": "count", "batch": "count",
                                     "init_from": "text", "hardware": "text", "data": "text", "recipe": "text"},
                 "summary.json": {"wall_s": "number"}}
"""The fields of the session's records the lineage entry copies, and what each must be (or null)."""
MAX_TEXT = 4000
"""The longest text field copied into the model card (gpu_session writes a few hundred characters)."""


def check_records(folder: Path) -> None:
    """The session's records are read (or refused) before the evaluation, not after it, and the fields the lineage
    entry copies are of their kind (`RECORD_FIELDS`): a string of minutes or a NaN never reaches the model card. No
    file of the candidate is read through a link that leads out of its folder."""
    import math

    from scenes.files import is_within

    for rel in ("run", "run/final.safetensors", "run/final.json", "run/last.pt", *RECORD_FIELDS):
        if os.path.lexists(folder / rel) and not is_within(folder / rel, folder):  # never read through a link out
            raise UsageError(f"--candidate: {str(folder / rel)!r} leads outside the candidate folder (a link to "
                             f"{os.path.realpath(folder / rel)!r}); expected the files the session brought back")
    for name, fields in RECORD_FIELDS.items():
        record = _read(folder / name)
        for key, kind in fields.items():
            v = record.get(key)
            ok = (v is None or (kind == "text" and isinstance(v, str) and len(v) <= MAX_TEXT)
                  or (kind != "text" and isinstance(v, (int, float)) and not isinstance(v, bool)
                      and abs(v) < 1e300 and math.isfinite(v) and v >= 0  # a 400-digit integer: no float of it
                      and (kind == "number" or float(v).is_integer())))
            if not ok:
                expected = {"text": f"a string of at most {MAX_TEXT} characters", "number": "a finite number >= 0",
                            "count": "a whole number >= 0"}[kind]
                raise UsageError(f"--candidate: {str(folder / name)!r} field {key!r} is {json.dumps(v)[:60]}; "
                                 f"expected {expected} or null (as orchestrate.gpu_session writes it)")


def lineage_entry(folder: Path, new: dict, old: dict | None, shipped: bool) -> dict:
    """The model card's record of a relay run, shipped or not."""
    card, summary = _read(folder / "model_card.json"), _read(folder / "summary.json")
    return {"stage": f"GPU relay run (orchestrate.gpu_session, orchestrate.ship), {time.strftime('%Y-%m-%d')}"
                     f"{'' if shipped else ' (not shipped)'}",
            "init_from": card.get("init_from"), "hardware": card.get("hardware"),
            "minutes": card.get("train_minutes"), "wall_s": summary.get("wall_s"),
            # the lineage table's column, as every other stage records it (training time, here on the GPU)
            "hours": round(card["train_minutes"] / 60, 3) if card.get("train_minutes") is not None else None,
            "steps": card.get("steps"), "batch": card.get("batch"), "data": card.get("data"),
            "recipe": card.get("recipe"), "shipped": shipped,
            "fixed_validation": {"all": round(new["mean"], 2), "gain": round(new["gain"], 2), "probes": new["probes"]},
            "shipped_model_fixed_validation": round(old["mean"], 2) if old else None,
            "diligent": new["diligent"], "shipped_model_diligent": old["diligent"] if old else None}


def decide(opts: ShipOptions) -> bool:
    """Score, decide, record (module doc); returns whether the candidate was shipped."""
    import torch

    from orchestrate.train_recipe import MEASURED_KEYS, VALIDATION_DATA, _display, _probe_card, install_weights
    from unips.checkpoint import git_revision
    from unips.models import load_model, pretrained_entry
    from unips.models.registry import read_model_card
    from unips.train import TrainConfig

    folder, val = Path(opts.candidate), Path(opts.val)
    diligent = None if opts.diligent in (None, "none") else Path(opts.diligent)
    from scenes.cli.outputs import check_not_being_written

    check_not_being_written(val, "--val")  # scored twice: a dataset still growing would decide the shipping
    check_records(folder)
    with tempfile.TemporaryDirectory() as scratch:
        weights, name = candidate_weights(folder, Path(scratch))
        entry = pretrained_entry(name)
        card = read_model_card(entry.card_path)  # read before the scoring: a damaged card is refused first
        lineage = card.get("lineage", [])
        if not isinstance(lineage, list) or not all(
                isinstance(s, dict) and isinstance(s.get("steps") or 0, int) for s in lineage):
            raise ValueError(f"model card {str(entry.card_path)!r}: its lineage is not a list of stages, each with "
                             "its steps a whole number or null (restore it)")
        current = entry.weights_path
        new = score(weights, val, diligent, opts.threads)
        old = score(current, val, diligent, opts.threads) if current.is_file() else None
        shipped = old is None or new["mean"] < old["mean"]
        print(f"fixed validation, all images: candidate {name} {new['mean']:.2f} deg, shipped "
              + (f"{old['mean']:.2f} deg" if old else "none yet")
              + (" -> shipped" if shipped else " -> not shipped (not lower)"), flush=True)
        record = lineage_entry(folder, new, old, shipped)
        card["lineage"] = [*card.get("lineage", []), record]
        if shipped:
            val_pixels = TrainConfig().val_pixels
            for key in MEASURED_KEYS:
                if key in card:
                    card[f"replaced_model_{key}"] = card.pop(key)
            model, meta = load_model(weights)
            card.update(
                {
                    "model": name,
                    "weights": _display(current),
                    "parameters": sum(p.numel() for p in model.parameters()),
                    "validation_data": (
                        f"orchestrate/train_recipe.py fixed validation set: wildgen.make {VALIDATION_DATA}"
                    ),
                    "steps": sum(s.get("steps") or 0 for s in card["lineage"] if s.get("shipped", True)),
                    "validation_mean_deg": round(new["mean"], 2),
                    "hardware": record["hardware"]
                    or f"{platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__}",
                    "git_revision": git_revision(REPO),
                    "probes_fixed_validation": _probe_card(new["_res"], val_pixels),
                    "replaced_model_probes_fixed_validation": _probe_card(old["_res"], val_pixels) if old else None,
                }
            )
            install_weights(weights, entry, card)
        else:
            from scenes.files import write_json

            write_json(entry.card_path, card, indent=1)
    print(f"{'shipped' if shipped else 'recorded'}: {_display(entry.card_path)} lineage "
          f"+1 ({len(card['lineage'])} entries)" + (f"; weights {_display(current)}" if shipped else ""), flush=True)
    return shipped


COMMAND = Command(ShipOptions, prog="python -m orchestrate.ship", description=__doc__)


def main(argv: list[str] | None = None) -> int:
    try:
        decide(COMMAND.parse(argv).validate())
    except (*INPUT_ERRORS, OSError) as exc:
        return report_error(exc)
    return 0


if __name__ == "__main__":  # Ctrl-C stops the work whole, in one line (scenes.cli.supervise)
    from scenes.cli.supervise import run_supervised

    stopped = ("interrupted: the shipped weights and the model card are each whole, as they were unless it said it "
               "shipped; run it again")
    sys.exit(run_supervised("orchestrate.ship", main, stopped))
