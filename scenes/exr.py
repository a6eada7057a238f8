"""Float EXR files: written with channels Y or R, G, B (ZIP); read strictly: pixels that fill the image's frame
(a data window off the display window is refused) and one image (a file of one layer, `beauty.R`, `beauty.G`, ...
as multilayer renderers write, is read as that layer; several layers are refused)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from scenes.files import atomic_write, not_a_file


def write_exr(path: str | Path, data: np.ndarray) -> None:
    """float32 (H, W), (H, W, 1) or (H, W, 3) -> EXR with channels Y or R, G, B (ZIP compression)."""
    import OpenEXR

    data = np.asarray(data, np.float32)
    if data.ndim == 3 and data.shape[2] == 1:
        data = data[:, :, 0]
    if data.ndim == 2:
        channels = {"Y": np.ascontiguousarray(data)}
    elif data.ndim == 3 and data.shape[2] == 3:
        channels = {c: np.ascontiguousarray(data[:, :, i]) for i, c in enumerate("RGB")}
    else:
        raise ValueError(f"write_exr: data shape {data.shape} is not (H, W), (H, W, 1) or (H, W, 3)")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}

    def write(tmp: Path) -> None:
        # OpenEXR replaces the dict's values with Channel objects: hand it a copy.
        try:
            with OpenEXR.File(header, dict(channels)) as f:
                f.write(str(tmp))
        except RuntimeError as exc:  # OpenEXR reports a full disk or an unwritable folder this way
            said = str(exc).replace(str(tmp), str(path))  # the file the user knows, not its temporary name
            raise OSError(f"could not write {str(path)!r}: {said}") from exc

    atomic_write(path, write)


def exr_channels(path: Path) -> dict[str, np.ndarray]:
    import OpenEXR

    if why := not_a_file(path):
        raise FileNotFoundError(f"EXR file {str(path)!r} {why}")
    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            windows = [tuple(map(tuple, np.asarray(f.header()[k]).tolist())) for k in ("dataWindow", "displayWindow")]
            channels = {k: np.asarray(v.pixels, np.float32) for k, v in f.channels().items()}
    except Exception as exc:  # OpenEXR raises several types for corrupt files
        raise ValueError(f"cannot read EXR {str(path)!r}: {exc}") from exc
    if windows[0] != windows[1]:  # its pixels would be taken as the frame's: shifted against every other file
        raise ValueError(f"EXR {str(path)!r}: its data window {windows[0]} is not its display window {windows[1]}; "
                         "expected pixels that fill the image's frame (save it uncropped)")
    shapes = {k: v.shape for k, v in channels.items()}
    if len(set(shapes.values())) > 1:  # subsampled channels (luminance/chroma: RY, BY at half size)
        sizes = ", ".join(f"{k} {v[1]}x{v[0]}" for k, v in sorted(shapes.items()))
        raise ValueError(f"EXR {str(path)!r}: its channels differ in size ({sizes}); expected full-size channels "
                         "(R, G, B or one), not luminance/chroma (save it as RGB)")
    return _one_layer(channels, path)


def _one_layer(channels: dict[str, np.ndarray], path: Path) -> dict[str, np.ndarray]:
    """An EXR's channels by plain name (R, G, B, A, Y): a file of one layer (`beauty.R`, `beauty.G`, ... as
    multilayer renderers write) is read as that layer; a file of several layers is refused (which one is meant?)."""
    layers = {name.rpartition(".")[0] for name in channels}
    if layers == {""}:
        return channels
    if len(layers) == 1:
        return {name.rpartition(".")[2]: data for name, data in channels.items()}
    raise ValueError(f"EXR {str(path)!r} holds several layers ({', '.join(sorted(n or '(none)' for n in layers))}); "
                     "expected one image (R, G, B or one channel)")


def read_exr(path: str | Path) -> np.ndarray:
    """EXR -> float32 (H, W, C): RGB when present, else its single channel, else all channels by name."""
    ch = exr_channels(Path(path))
    if all(c in ch for c in "RGB"):
        return np.stack([ch["R"], ch["G"], ch["B"]], -1)
    if len(ch) == 1:
        return next(iter(ch.values()))[:, :, None]
    names = sorted(ch)
    return np.stack([ch[k] for k in names], -1)
