"""The camera sensor: what turns the linear radiance of an image into the integers of its PNG file.

A `Sensor` is plain data (a docstring per field, JSON round trip) recorded in each object folder's scene.json
(`sensor_record`), so every image can be re-derived from its float radiance (`aux/radiance_XXX.exr`), its
exposure (`images[i].exposure`) and its recorded noise seed (`rederive_image`). The radiance EXR is never
changed: the PNG files are what this sensor would write. `SENSORS` is the table of presets (`ideal` is the
noise-free 16-bit linear output the generator has always written, byte for byte).

The model, per pixel p and colour channel c, for x the linear value after the image's exposure (x = 1 is the
white level of an ideal file):

1. optics:          y = x * exposure * V(p), with V the cos^4 vignetting law (`vignetting_map`);
2. colour filter:   y_c = y_c * sensitivity_c; with a Bayer colour filter array (`cfa`) each pixel keeps only
                    the channel of its filter (the mosaic, (H, W));
3. electrons:       e = Poisson(full_well * y_c) + Normal(0, read_noise^2): the signal in electrons is
                    y_c * full_well, photon arrival is Poisson (shot noise), the read-out adds Gaussian noise
                    of read_noise electrons rms (noise-free when `full_well` is None: e / full_well = y_c);
4. full well:       s = min(e / full_well, 1): a pixel holds at most full_well electrons (saturation);
5. demosaic:        with a CFA, s (H, W) -> (H, W, 3) by `demosaic` (colour-demosaicing);
6. white balance:   n_c = min(white_balance_c * s_c, 1);
7. response:        v = black + (1 - black) * f(n): f(n) = n for a linear response (values below 0 are kept
                    down to the black level, as a raw sensor keeps read noise below its pedestal), the sRGB
                    encoding or n^(1 / gamma) of clip(n, 0, 1) otherwise;
8. quantisation:    DN = round(clip(v, 0, 1) * (2^bits - 1)); 8 bits are written as an 8-bit PNG, 16 bits as a
                    16-bit PNG, 12 bits as a 16-bit PNG holding DN * 16 (the most significant bits, as machine
                    vision cameras pack them).

Photon transfer (linear response, no CFA, away from 0 and from saturation), what the tests check: with the
gain K_c = (2^bits - 1) * (1 - black) * white_balance_c / full_well in DN per electron (`Sensor.gain`) and the
dark level D = (2^bits - 1) * black in DN (`Sensor.dark_level`), the mean and variance of DN are

    mean = D + K_c * full_well * y_c,    var = K_c * (mean - D) + K_c^2 * read_noise^2 + 1 / 12

(the last term is the rounding of step 8). Not modelled: dark current, fixed-pattern noise, a colour
correction matrix, the raw converter's quantisation before demosaicing, compression.

The noise of image i is drawn from `np.random.default_rng(noise_seed(images[i].seed, seed))`, Poisson first
then Normal over the whole array; the bytes are fixed for a given NumPy and colour-demosaicing version.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Callable

import numpy as np

# ------------------------------------------------------------------------------------------ tables

CFA_PATTERNS = ("none", "RGGB", "BGGR", "GRBG", "GBRG")
"""Colour filter arrays: none (every pixel sees R, G and B) or a Bayer pattern, its top-left 2 x 2 block
read row by row."""
DEMOSAIC_METHODS = {
    "bilinear": "demosaicing_CFA_Bayer_bilinear",
    "malvar2004": "demosaicing_CFA_Bayer_Malvar2004",
    "menon2007": "demosaicing_CFA_Bayer_Menon2007",
}
"""Demosaicing algorithm -> its colour-demosaicing function: bilinear interpolation, Malvar, He and Cutler
(2004, gradient-corrected linear filters, the algorithm of MATLAB's `demosaic`), Menon, Andriani and Calvagno
(2007, directional filtering with a posteriori decision, sharper edges, about 3x slower)."""
BIT_DEPTHS = {8: (np.uint8, 0), 12: (np.uint16, 4), 16: (np.uint16, 0)}
"""Bits per channel -> (PNG pixel type, left shift of the stored value): 12 bits live in a 16-bit PNG."""


def _linear(n: np.ndarray, gamma: float) -> np.ndarray:
    return n


def _srgb(n: np.ndarray, gamma: float) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # colour-science warns about optional matplotlib at import
        from colour.models import eotf_inverse_sRGB

    return np.asarray(eotf_inverse_sRGB(np.clip(n, 0.0, 1.0)), dtype=n.dtype)


def _gamma(n: np.ndarray, gamma: float) -> np.ndarray:
    return np.clip(n, 0.0, 1.0) ** n.dtype.type(1.0 / gamma)


RESPONSES: dict[str, Callable[[np.ndarray, float], np.ndarray]] = {
    "linear": _linear,
    "srgb": _srgb,
    "gamma": _gamma,
}
"""Tone response f of step 7: 'linear' (file value proportional to light: raw and machine-vision output),
'srgb' (IEC 61966-2-1 encoding, colour-science's `eotf_inverse_sRGB`: phones, webcams, most 8-bit files),
'gamma' (n^(1 / gamma))."""


# ------------------------------------------------------------------------------------------ sensor


@dataclass
class Sensor:
    """One camera sensor and its processing, from light to file (the model in the module docstring)."""

    name: str = "custom"
    """Name of the preset it came from (a key of `SENSORS`), or 'custom'."""
    about: str = ""
    """What the sensor imitates, in one sentence."""
    exposure: float = 1.0
    """Factor on top of each image's recorded exposure (step 1): above 1 over-exposes, more pixels clip."""
    vignetting: float = 0.0
    """Light lost at the image corners, following the cos^4 law (0: none, 0.3: the corners get 70 % of the
    centre's light); in [0, 1)."""
    sensitivity: tuple[float, float, float] = (1.0, 1.0, 1.0)
    """Relative sensitivity of the sensor's R, G and B pixels (step 2): a white surface gives raw signals in
    this ratio, which the white balance undoes."""
    cfa: str = "none"
    """Colour filter array (step 2): 'none' or a Bayer pattern RGGB, BGGR, GRBG, GBRG."""
    demosaic: str = "malvar2004"
    """Demosaicing algorithm of a Bayer mosaic (step 5): a key of `DEMOSAIC_METHODS`."""
    full_well: float | None = None
    """Electrons a pixel collects at signal 1 (step 3), where it saturates; None: noise-free."""
    read_noise: float = 0.0
    """Gaussian read-out noise in electrons rms (step 3); needs `full_well`."""
    white_balance: tuple[float, float, float] = (1.0, 1.0, 1.0)
    """Gains on the linear R, G, B after demosaicing (step 6); 1 / sensitivity gives a neutral white."""
    response: str = "linear"
    """Tone response (step 7): a key of `RESPONSES` (linear, srgb, gamma)."""
    gamma: float = 2.2
    """Exponent of the 'gamma' response: the file holds n^(1 / gamma)."""
    black_level: float = 0.0
    """Pedestal of the file values (step 7), as a fraction of the full scale: 0.01 at 12 bits is 41 DN."""
    bits: int = 16
    """Bits per channel of the file (step 8): 8, 12 (stored in a 16-bit PNG as DN * 16) or 16."""

    # --- derived -----------------------------------------------------------------------------------

    @property
    def max_code(self) -> int:
        """The largest DN of the file's bit depth (before the 12-bit shift)."""
        return (1 << self.bits) - 1

    @property
    def noisy(self) -> bool:
        """True when images get shot and read noise (a random generator is needed)."""
        return self.full_well is not None

    def gain(self, channel: int = 1) -> float:
        """K in DN per electron of `channel` (linear response): (2^bits - 1) (1 - black) wb_c / full_well."""
        if self.full_well is None:
            raise ValueError(f"sensor {self.name!r}: a noise-free sensor has no gain in DN per electron")
        return self.max_code * (1.0 - self.black_level) * self.white_balance[channel] / self.full_well

    @property
    def dark_level(self) -> float:
        """The mean DN of a black pixel: (2^bits - 1) * black_level."""
        return self.max_code * self.black_level

    # --- plain data --------------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["sensitivity"], d["white_balance"] = list(self.sensitivity), list(self.white_balance)
        return d

    @classmethod
    def from_dict(cls, d: Any, where: str = "sensor") -> "Sensor":
        """A Sensor from its dict (unknown keys refused by name); validated."""
        if not isinstance(d, dict):
            raise ValueError(f"{where}: expected an object, got {type(d).__name__}")
        names = [f.name for f in fields(cls)]
        unknown = sorted(set(d) - set(names))
        if unknown:
            raise ValueError(f"{where}: unknown field(s) {', '.join(unknown)}, expected some of {', '.join(names)}")
        kwargs = dict(d)
        for key in ("sensitivity", "white_balance"):
            if isinstance(kwargs.get(key), list):
                kwargs[key] = tuple(kwargs[key])
        return cls(**kwargs).validate(where)

    def validate(self, where: str = "sensor") -> "Sensor":
        """Raise ValueError (one line naming `where`.field, the value and what was expected); returns self."""
        def bad(name: str, expected: str) -> ValueError:
            return ValueError(f"{where}.{name}: got {getattr(self, name)!r}, expected {expected}")

        def number(name: str, lo: float, hi: float | None = None, lo_open: bool = False) -> None:
            v = getattr(self, name)
            ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            if not (ok and (v > lo if lo_open else v >= lo) and (hi is None or v < hi)):
                raise bad(
                    name, f"a number {'>' if lo_open else '>='} {lo:g}" + ("" if hi is None else f" and < {hi:g}")
                )

        for name in ("name", "about"):
            if not isinstance(getattr(self, name), str):
                raise bad(name, "a string")
        number("exposure", 0, lo_open=True)
        number("vignetting", 0, 1)
        for name in ("sensitivity", "white_balance"):
            v = getattr(self, name)
            if not (isinstance(v, (tuple, list)) and len(v) == 3 and all(
                    isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) and c > 0 for c in v)):
                raise bad(name, "three numbers > 0 (R, G, B)")
        if self.cfa not in CFA_PATTERNS:
            raise bad("cfa", f"one of {', '.join(CFA_PATTERNS)}")
        if self.demosaic not in DEMOSAIC_METHODS:
            raise bad("demosaic", f"one of {', '.join(DEMOSAIC_METHODS)}")
        if self.full_well is not None:
            number("full_well", 0, lo_open=True)
        number("read_noise", 0)
        if self.read_noise > 0 and self.full_well is None:
            raise bad("read_noise", "0 for a noise-free sensor (full_well None); give full_well too")
        if self.response not in RESPONSES:
            raise bad("response", f"one of {', '.join(RESPONSES)}")
        number("gamma", 0, lo_open=True)
        number("black_level", 0, 0.5)
        if isinstance(self.bits, bool) or self.bits not in BIT_DEPTHS:
            raise bad("bits", f"one of {', '.join(map(str, BIT_DEPTHS))}")
        return self


SENSORS: dict[str, Sensor] = {
    s.name: s.validate(f"SENSORS[{s.name!r}]")
    for s in (
        Sensor(
            name="ideal",
            about="A perfect linear 16-bit camera: no noise, no vignetting, no colour filter (the generator's "
                  "output before the sensor model, byte for byte).",
        ),
        Sensor(
            name="machine-vision",
            about="An industrial camera as in lab photometric stereo set-ups (e.g. DiLiGenT): linear 12-bit "
                  "output in 16-bit files, 10000 e- full well, 5 e- read noise, a small black level.",
            full_well=10000.0, read_noise=5.0, black_level=0.01, bits=12,
        ),
        Sensor(
            name="phone",
            about="A phone camera's processed output: 8-bit sRGB, RGGB Bayer filter demosaiced, 2000 e- full "
                  "well (small pixels), 3 e- read noise, white balance of daylight raw gains, 20 % corner "
                  "vignetting left after lens-shading correction.",
            vignetting=0.2, sensitivity=(0.5, 1.0, 2.0 / 3.0), cfa="RGGB", demosaic="malvar2004",
            full_well=2000.0, read_noise=3.0, white_balance=(2.0, 1.0, 1.5), response="srgb", bits=8,
        ),
        Sensor(
            name="webcam",
            about="A low-cost webcam: 8-bit gamma 2.2, RGGB Bayer filter demosaiced bilinearly, 1000 e- full "
                  "well, 8 e- read noise, 35 % corner vignetting, slight over-exposure.",
            exposure=1.15, vignetting=0.35, sensitivity=(0.6, 1.0, 0.8), cfa="RGGB", demosaic="bilinear",
            full_well=1000.0, read_noise=8.0, white_balance=(1.0 / 0.6, 1.0, 1.25), response="gamma", gamma=2.2,
            bits=8,
        ),
    )
}
"""Sensor presets by name (`wildgen.make --sensor NAME`, `python -m wildgen.sensor --sensor NAME`)."""


def sensor_named(name: str, flag: str = "--sensor") -> Sensor:
    """The preset `name` of `SENSORS`; ValueError naming `flag` and the known presets."""
    if name not in SENSORS:
        raise ValueError(f"{flag}: unknown sensor {name!r}, expected one of {', '.join(SENSORS)}")
    return replace(SENSORS[name])


# ------------------------------------------------------------------------------------------ steps


def vignetting_map(height: int, width: int, vignetting: float) -> np.ndarray:
    """(H, W) float64 relative illumination V of the cos^4 law, 1 at the centre and 1 - vignetting at the
    corners: V = 1 / (1 + (t r)^2)^2 with r the distance of a pixel centre from the image centre over half the
    diagonal, t = tan of the corner's field angle = sqrt((1 - vignetting)^(-1/2) - 1)."""
    t = math.sqrt((1.0 - vignetting) ** -0.5 - 1.0)
    yy = np.arange(height) + 0.5 - height / 2.0  # (H,)
    xx = np.arange(width) + 0.5 - width / 2.0  # (W,)
    r2 = (yy[:, None] ** 2 + xx[None, :] ** 2) / ((height / 2.0) ** 2 + (width / 2.0) ** 2)  # (H, W)
    return 1.0 / (1.0 + t * t * r2) ** 2


def _colour_demosaicing():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # colour-science warns about optional matplotlib at import
        import colour_demosaicing

    return colour_demosaicing


def mosaic(rgb: np.ndarray, pattern: str) -> np.ndarray:
    """(H, W, 3) -> (H, W): each pixel keeps the channel of its Bayer filter (same dtype)."""
    return np.asarray(_colour_demosaicing().mosaicing_CFA_Bayer(rgb, pattern), dtype=rgb.dtype)


def demosaic(cfa: np.ndarray, pattern: str, method: str) -> np.ndarray:
    """(H, W) Bayer mosaic -> (H, W, 3) by `DEMOSAIC_METHODS[method]` (same dtype).

    The mosaic is first padded by 2 pixels, mirrored without repeating the edge: that keeps the Bayer phase
    (row -1 mirrors row 1, same parity), so the border pixels are interpolated from pixels of the right colour
    (colour-demosaicing's own border handling mixes colours there) and a flat colour comes back exactly."""
    fn = getattr(_colour_demosaicing(), DEMOSAIC_METHODS[method])
    pad = 2
    padded = np.pad(cfa.astype(np.float64), pad, mode="reflect" if min(cfa.shape) > pad else "symmetric")  # (H+4, W+4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rgb = np.asarray(fn(padded, pattern))  # (H+4, W+4, 3)
    return np.ascontiguousarray(rgb[pad:-pad, pad:-pad], dtype=cfa.dtype)


def store(dn: np.ndarray, bits: int) -> np.ndarray:
    """Integer DN (any integer or integral float array) -> the PNG's pixel array of `bits` (12 bits shifted)."""
    dtype, shift = BIT_DEPTHS[bits]
    return (dn.astype(np.uint32) << shift).astype(dtype) if shift else dn.astype(dtype)


def apply_sensor(linear: np.ndarray, sensor: Sensor, rng: np.random.Generator | None = None) -> np.ndarray:
    """The file pixels of one image: (H, W, 3) linear float (>= 0, after the image's exposure; 1 is the white
    level) -> (H, W, 3) uint8 (8 bits) or uint16 (12 bits as DN * 16, 16 bits), by the model of the module
    docstring. `rng` draws the noise (required when `sensor.noisy`). The arithmetic stays in the input's float
    type, so `ideal` gives exactly `scenes.images.to_uint16(linear)`."""
    x = np.asarray(linear)
    if x.ndim != 3 or x.shape[2] != 3 or not np.issubdtype(x.dtype, np.floating):
        raise ValueError(f"apply_sensor: expected a float (H, W, 3) image, got {x.dtype} {x.shape}")
    if sensor.noisy and rng is None:
        raise ValueError(f"apply_sensor: sensor {sensor.name!r} adds noise and needs a random generator (rng)")
    ft = x.dtype.type
    h, w, _ = x.shape
    y = x * ft(sensor.exposure)  # (H, W, 3) step 1
    if sensor.vignetting:
        y = y * vignetting_map(h, w, sensor.vignetting).astype(x.dtype)[:, :, None]
    y = y * np.asarray(sensor.sensitivity, x.dtype)  # step 2
    if sensor.cfa != "none":
        y = mosaic(y, sensor.cfa)  # (H, W)
    if sensor.noisy:  # step 3, in electrons
        fw = float(sensor.full_well)
        electrons = rng.poisson(np.maximum(y, 0.0).astype(np.float64) * fw).astype(np.float64)
        if sensor.read_noise:
            electrons += rng.normal(0.0, float(sensor.read_noise), size=electrons.shape)
        y = (electrons / fw).astype(x.dtype)
    s = np.minimum(y, ft(1.0))  # step 4: full well
    if sensor.cfa != "none":
        s = demosaic(s, sensor.cfa, sensor.demosaic)  # (H, W, 3) step 5
    n = np.minimum(s * np.asarray(sensor.white_balance, x.dtype), ft(1.0))  # step 6
    b = ft(sensor.black_level)
    v = b + (ft(1.0) - b) * RESPONSES[sensor.response](n, sensor.gamma)  # step 7
    dn = np.round(np.clip(v, 0.0, 1.0) * float(sensor.max_code))  # step 8 (as to_uint16: clip, scale, round)
    return store(dn, sensor.bits)


# ------------------------------------------------------------------------------------------ reading back

INVERSE_RESPONSES: dict[str, Callable[[np.ndarray, float], np.ndarray]] = {
    "linear": lambda v, gamma: v,
    "srgb": lambda v, gamma: _srgb_decode(v),
    "gamma": lambda v, gamma: np.clip(v, 0.0, 1.0) ** gamma,
}
"""The inverse of each tone response (file value -> linear), for readers that need light, not file values."""


def _srgb_decode(v: np.ndarray) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from colour.models import eotf_sRGB

    return np.asarray(eotf_sRGB(np.clip(v, 0.0, 1.0)), dtype=np.float64)


def file_codes(values: np.ndarray, sensor: Sensor) -> np.ndarray:
    """The integer DN of file values as readers return them (8-bit / 255, 16-bit / 65535; 12 bits stored as
    DN * 16 in 16 bits): float64 DN in [0, 2^bits - 1]."""
    container = 255.0 if sensor.bits == 8 else 65535.0
    shift = BIT_DEPTHS[sensor.bits][1]
    return np.round(np.asarray(values, np.float64) * container) / float(1 << shift)


def saturation_value(sensor: Sensor) -> float:
    """The file value (as readers return it) of the largest code of the sensor's bit depth: a channel at or
    above it is clipped (12 bits in 16: 65520 / 65535, not 1)."""
    container = 255.0 if sensor.bits == 8 else 65535.0
    return (sensor.max_code << BIT_DEPTHS[sensor.bits][1]) / container


def linearize(values: np.ndarray, sensor: Sensor) -> np.ndarray:
    """Undo the deterministic steps of the model: (K, H, W, 3) or (H, W, 3) file values as readers return them
    -> float32 linear values x on the scale of the radiance times the image's exposure (noise stays; the
    demosaic is taken as the identity, which it is on smooth shading). Inverts steps 8 (codes), 7 (black level
    and response), 6 (white balance), 2 (sensitivity) and 1 (exposure, vignetting)."""
    v = file_codes(values, sensor) / float(sensor.max_code)
    b = sensor.black_level
    n = INVERSE_RESPONSES[sensor.response]((v - b) / (1.0 - b), sensor.gamma)
    x = n / np.asarray(sensor.white_balance, np.float64) / np.asarray(sensor.sensitivity, np.float64)
    h, w = values.shape[-3], values.shape[-2]
    if sensor.vignetting:
        x = x / vignetting_map(h, w, sensor.vignetting)[:, :, None]
    return (x / sensor.exposure).astype(np.float32)


# ------------------------------------------------------------------------------------------ files


def write_image(path: str | Path, pixels: np.ndarray) -> None:
    """(H, W, 3) uint8 or uint16 file pixels of `apply_sensor` -> an 8- or 16-bit RGB PNG, atomically."""
    from scenes.files import atomic_write
    from scenes.images import write_png16

    if pixels.dtype == np.uint16:
        write_png16(path, pixels)  # the writer of every 16-bit image: `ideal` gives today's bytes
        return
    if pixels.dtype != np.uint8 or pixels.ndim != 3 or pixels.shape[2] != 3:
        raise ValueError(f"write_image: expected (H, W, 3) uint8 or uint16 pixels, got {pixels.dtype} {pixels.shape}")
    import cv2

    path = Path(path)
    ok, data = cv2.imencode(path.suffix, np.ascontiguousarray(pixels[:, :, ::-1]))  # RGB -> OpenCV's BGR
    if not ok:
        raise OSError(f"could not encode {str(path)!r} (unsupported extension {path.suffix!r})")
    atomic_write(path, lambda tmp: tmp.write_bytes(data.tobytes()))


# ------------------------------------------------------------------------------------------ scene.json

SCENE_KEY = "sensor"
"""The scene.json key of the sensor record (an extra top-level key, `scenes.folder.format`)."""
_STREAM = 0x5E4502  # keeps the noise streams apart from any other use of the image seeds


def noise_seed(image_seed: int, seed: int = 0) -> int:
    """The noise seed of an image: a 32-bit integer drawn from (seed, the image's sampler seed)."""
    return int(np.random.SeedSequence([int(seed), int(image_seed), _STREAM]).generate_state(1, np.uint32)[0])


def sensor_record(sensor: Sensor, image_seeds: list[int], seed: int = 0) -> dict[str, Any]:
    """The scene.json value under `SCENE_KEY`: the sensor, the seed and each image's noise seed."""
    return {"model": sensor.validate().to_dict(), "seed": int(seed),
            "noise_seeds": [noise_seed(s, seed) for s in image_seeds]}


@dataclass
class SensorRecord:
    """What scene.json says about how its images were made from the radiance."""

    sensor: Sensor = field(default_factory=lambda: replace(SENSORS["ideal"]))
    """The sensor (`ideal` for folders written before the sensor model)."""
    seed: int = 0
    """The seed the noise seeds were drawn from."""
    noise_seeds: list[int] = field(default_factory=list)
    """Per image, the seed of `np.random.default_rng` that drew its noise."""


def read_sensor_record(extras: dict[str, Any], images: int, where: str = "the scene file") -> SensorRecord:
    """The sensor record of scene.json's extras (`scenes.folder.format.read_scene`); a folder without one was
    written by the ideal sensor. ValueError naming the bad field."""
    if SCENE_KEY not in extras:
        return SensorRecord(noise_seeds=[0] * images)
    rec = extras[SCENE_KEY]
    key = f"{where} {SCENE_KEY}"
    if not isinstance(rec, dict) or set(rec) != {"model", "seed", "noise_seeds"}:
        raise ValueError(f"{key}: expected an object with keys model, seed, noise_seeds, got {rec!r:.80}")
    sensor = Sensor.from_dict(rec["model"], f"{key}.model")
    seeds = rec["noise_seeds"]
    if not isinstance(seeds, list) or len(seeds) != images or not all(
            isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in seeds):
        raise ValueError(
            f"{key}.noise_seeds: expected {images} non-negative integers (one per image), got {seeds!r:.80}"
        )
    if isinstance(rec["seed"], bool) or not isinstance(rec["seed"], int) or rec["seed"] < 0:
        raise ValueError(f"{key}.seed: expected a non-negative integer, got {rec['seed']!r}")
    return SensorRecord(sensor=sensor, seed=rec["seed"], noise_seeds=list(seeds))


def scale_camera_lights(camera_lights: list, factor: float) -> list:
    """A copy of scene.json's `camera_lights` with every directional irradiance times `factor` (the irradiance
    is recorded as the file sees it, so a sensor's exposure scales it)."""
    import copy

    out = copy.deepcopy(camera_lights)
    for per_image in out:
        for light in per_image.get("directional", []):
            light["irradiance"] = [float(v) * factor for v in light["irradiance"]]
    return out


def rederive_image(radiance: np.ndarray, exposure: float, sensor: Sensor, noise_seed_: int) -> np.ndarray:
    """The file pixels of one image from its recorded inputs: (H, W, 3) float radiance (aux/radiance_XXX.exr),
    images[i].exposure, the sensor and the image's recorded noise seed -> (H, W, 3) uint8 / uint16."""
    rng = np.random.default_rng(noise_seed_) if sensor.noisy else None
    return apply_sensor(radiance * exposure, sensor, rng)


def check_file_bits(sensor: Sensor, files: list, where: str) -> Sensor:
    """`sensor`, once the first of its `files` holds the pixel type its bits are written as (`BIT_DEPTHS`): a record
    edited, or copied beside other files, would undo the sensor at the wrong scale. ValueError naming `where`."""
    import cv2

    img = cv2.imread(str(files[0]), cv2.IMREAD_UNCHANGED) if files else None
    want = BIT_DEPTHS[sensor.bits][0]
    if img is not None and img.dtype != want:
        raise ValueError(f"{where}: its sensor records {sensor.bits} bits, written as {np.dtype(want).itemsize * 8}"
                         f"-bit files, but {files[0].name} is {img.dtype.itemsize * 8}-bit; expected the files the "
                         "sensor wrote (restore the record or the images)")
    return sensor
