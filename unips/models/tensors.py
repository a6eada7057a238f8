"""What every weight loader asks of the tensors it reads (`unips.models.builder.load_state_strict` for our model
files, `unips.models.official.read_official` for each of the authors' files): tensors, finite where floating point,
and of the kind the model holds (floating point where the model's is, integer where the model's is: a float
parameter given as int64 would be cast without a word, and a NaN weight is found only after a forward pass)."""

from __future__ import annotations

import re
from typing import Any, Mapping

import torch


def _kind(t: torch.Tensor) -> str:
    if t.is_floating_point():
        return "floating-point"
    if t.is_complex():
        return "complex"
    return "boolean" if t.dtype == torch.bool else "integer"


def _dtype(t: torch.Tensor) -> str:
    return str(t.dtype).removeprefix("torch.")


def check_weights(state: Mapping[str, Any], source: str, expected: Mapping[str, torch.Tensor] | None = None) -> None:
    """Every value of `state` a tensor, every floating-point one finite and, where `expected` (the model's own state
    dict) has its name, of the model's kind; else one ValueError beginning with `source` (the file) that names the
    tensor and what it holds."""
    for key, value in state.items():
        if not isinstance(value, torch.Tensor):
            raise ValueError(f"{source}: entry {key} is a {type(value).__name__}, expected a tensor")
        if value.layout != torch.strided or value.is_meta or value.is_quantized:  # no values to run, or none here
            what = "a meta tensor (no values)" if value.is_meta else "quantized" if value.is_quantized else \
                f"a {str(value.layout).removeprefix('torch.')} tensor"
            raise ValueError(f"{source}: tensor {key} is {what}; expected dense weights, as a training run saves them")
        own = expected.get(key) if expected is not None else None
        if own is not None and _kind(own) != _kind(value):
            raise ValueError(f"{source}: tensor {key} is {_dtype(value)}, expected {_kind(own)} values (the model "
                             f"holds {_dtype(own)}): a damaged file, or not weights of this network")
        if value.is_floating_point() or value.is_complex():
            if value.is_floating_point() and value.element_size() == 1:  # float8: no network of ours holds it
                raise ValueError(f"{source}: tensor {key} is {_dtype(value)}, expected float16, bfloat16 or float32 "
                                 "weights (8-bit floats are a lossy export, not weights to run)")
            # as the model will hold them: 1e300 in float64 is finite, and infinite once loaded as float32
            held = value.to(own.dtype) if own is not None and own.is_floating_point() and value.is_floating_point() \
                else value
            finite = torch.isfinite(held)
            if not bool(finite.all()):
                nan = int(torch.isnan(held).sum())
                inf = held.numel() - int(finite.sum()) - nan
                cast = f" once held as {_dtype(own)}" if held is not value else ""
                raise ValueError(f"{source}: tensor {key} holds {nan} NaN and {inf} infinite values{cast} (of "
                                 f"{value.numel()}); expected finite weights (a training run that diverged, or a "
                                 "damaged file)")


def load_torch_file(path: Any, what: str, map_location: Any = "cpu") -> Any:
    """`torch.load` of an untrusted file with the weights-only unpickler; a file it refuses is one ValueError naming
    `path` and `what` it should be: corrupt or truncated, or a whole pickle of objects other than tensors and plain
    values (building those could run code from the file, so it is not read)."""
    import warnings

    try:
        with warnings.catch_warnings():  # torch's notes on a foreign pickle protocol: the errors below say enough
            warnings.simplefilter("ignore", UserWarning)
            return torch.load(path, map_location=map_location, weights_only=True)
    except Exception as exc:  # pickle, zipfile and torch raise their own errors for corrupt or foreign files
        if "Unsupported global" in str(exc):  # a whole pickle naming a class to build (a NumPy array, a module)
            raise ValueError(f"{str(path)!r}: the {what} holds Python objects other than tensors and plain values (a "
                             "NumPy array, a class): not read, as building them could run code from the file") from None
        if "Weights only load failed" in str(exc):  # torch's advice to load it fully is never followed: say what
            advice = ("Weights only load failed", "Please file an issue", "Check the documentation")
            detail = next((ln.strip().removeprefix("WeightsUnpickler error:").strip() for ln in str(exc).splitlines()
                           if ln.strip() and not ln.strip().startswith(advice)
                           and ln.strip() != "WeightsUnpickler error:"), "")
            raise ValueError(f"{str(path)!r}: not a readable {what}: the tensors-only reader refuses it "
                             f"({detail[:120]}): the file is corrupt, or a pickle torch.save did not write (not read "
                             "further: loading it fully could run code from the file)") from None
        lines = str(exc).strip().splitlines()
        first = re.sub(r"\. This is an internal miniz error.*", "", lines[0]) if lines else ""  # torch's own advice
        why = f"{type(exc).__name__}: {first[:160]}" if first else type(exc).__name__
        raise ValueError(f"{str(path)!r}: not a readable {what}, the file is corrupt or truncated ({why})") from exc


MAX_HEADER_BYTES = 100 * 2**20
"""The longest .safetensors header read (the format's own reader allows 100 MB)."""


def stored_format(path: Any) -> str | None:
    """Which of the two weights formats the file's bytes say it is, whatever its name: "safetensors" (an 8-byte
    header length, then the JSON header), "torch" (torch.save's zip archive: a member `<name>/data.pkl`), or None
    (neither, or a file too damaged to tell: the reader chosen by its name says what is wrong)."""
    import struct
    import zipfile

    with open(path, "rb") as f:
        head = f.read(9)
    if len(head) == 9 and head[8:9] == b"{" and 0 < struct.unpack("<Q", head[:8])[0] <= MAX_HEADER_BYTES:
        return "safetensors"
    if head[:2] == b"PK":
        try:
            with zipfile.ZipFile(path) as z:
                names = z.namelist()
        except (zipfile.BadZipFile, OSError, ValueError):
            return None
        return "torch" if any(n.count("/") == 1 and n.endswith("/data.pkl") for n in names) else None
    return None


def check_stored_format(path: Any, expected: str) -> None:
    """A ValueError of one line when the file at `path`, read by its name as `expected` ("safetensors" or
    "torch"), holds the other format (a file renamed by hand): named with the way out, where the reader chosen by
    the name would call it corrupt."""
    found = stored_format(path)
    if found is None or found == expected:
        return
    from pathlib import Path

    path = Path(path)
    have, named = (".safetensors", ".pt") if found == "safetensors" else (".pt", ".safetensors")
    raise ValueError(f"{str(path)!r}: a {have} weights file named {named} (read by its name as the wrong format); "
                     f"rename it to {path.with_suffix(have).name!r}"
                     + (" with its .json sidecar beside it" if found == "safetensors" else ""))


def check_safetensors_header(path: Any) -> None:
    """The JSON header of a .safetensors file names each tensor once: a header naming one twice is ambiguous (the
    format's reader keeps one of them without a word, so two readers may load different weights from one file); a
    ValueError naming the file and the tensor. Other damage is left to the format's reader, which names it."""
    import json
    import struct

    def unique(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
        seen: set[str] = set()
        for key, _ in pairs:
            if key in seen:
                raise ValueError(f"{str(path)!r}: its header names the tensor {key!r} twice; expected each tensor "
                                 "once (a damaged or crafted weights file)")
            seen.add(key)
        return dict(pairs)

    with open(path, "rb") as f:
        head = f.read(8)
        size = struct.unpack("<Q", head)[0] if len(head) == 8 else 0
        text = f.read(size) if 0 < size <= MAX_HEADER_BYTES else b""
    try:
        json.loads(text.decode("utf-8"), object_pairs_hook=unique)
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError):  # not a header: the format's reader says so
        pass
