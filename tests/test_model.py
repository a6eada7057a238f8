"""GLC-UniPS models: registry, shapes, invariances, chunked decoding, bounded memory, configs."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import torch

from unips.models import GLCConfig, create_model, list_models
from unips.models.glc import pixel_centre_coords

REPO = Path(__file__).resolve().parents[1]


def _inputs(b: int = 1, k: int = 3, h: int = 32, w: int = 32, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    images = torch.rand(b, k, 3, h, w, generator=g) * 2  # (B, K, 3, H, W)
    yy, xx = torch.meshgrid(torch.arange(h), torch.arange(w), indexing="ij")
    disk = ((yy - h / 2 + 0.5) ** 2 + (xx - w / 2 + 0.5) ** 2 < (0.42 * min(h, w)) ** 2).float()
    return images, disk.expand(b, 1, h, w).clone()


@pytest.fixture(scope="module")
def test_model() -> torch.nn.Module:
    torch.manual_seed(0)
    return create_model("glc-test").eval()


def test_registry_lists_the_models() -> None:
    assert {"glc-base", "glc-tiny", "glc-small", "glc-test", "glc-unips"} <= set(list_models())


def test_param_counts_are_sane(capsys) -> None:
    counts = {name: create_model(name).num_parameters() for name in ("glc-test", "glc-tiny")}
    with capsys.disabled():
        print(f"\nparameter counts: {counts}")
    assert 10_000 < counts["glc-test"] < 300_000
    assert 200_000 < counts["glc-tiny"] < 2_500_000


def test_glc_base_matches_the_paper() -> None:
    """Our reading at the paper's size (the published network, glc-unips, is tests/test_glc_unips.py's)."""
    torch.manual_seed(0)
    model = create_model("glc-base").eval()
    n = model.num_parameters()
    print(f"glc-base parameters: {n}")
    assert 66e6 < n < 72e6  # paper: about 69 M
    feats = []
    model.encoder.backbone.register_forward_hook(lambda mod, inp, out: feats.append([tuple(f.shape) for f in out]))
    images, _ = _inputs(k=2, h=64, w=64)
    mask = torch.zeros(1, 1, 64, 64)
    mask[..., 28:36, 30:38] = 1  # few pixels: the 70 M decoder costs about 11 MFLOP per pixel and image
    with torch.no_grad():
        out = model(images, mask)
    # Swin-S multi-scale features at canonical 256: 64x64x96 .. 8x8x768 (channels last), per image.
    assert feats == [[(2, 64, 64, 96), (2, 32, 32, 192), (2, 16, 16, 384), (2, 8, 8, 768)]]
    assert tuple(out.shape) == (1, 3, 64, 64)
    norms = out.norm(dim=1)[mask[:, 0] > 0]
    assert torch.allclose(norms, torch.ones_like(norms), atol=1e-5)


@pytest.mark.parametrize("h,w", [(32, 32), (24, 40)])
def test_output_unit_norm_and_input_size(test_model, h: int, w: int) -> None:
    images, mask = _inputs(b=2, k=3, h=h, w=w)
    with torch.no_grad():
        out = test_model(images, mask)
    assert tuple(out.shape) == (2, 3, h, w)
    inside = mask[:, 0] > 0
    norms = out.norm(dim=1)
    assert torch.allclose(norms[inside], torch.ones_like(norms[inside]), atol=1e-5)
    assert torch.all(out.permute(1, 0, 2, 3)[:, ~inside] == 0)


def test_permutation_invariance(test_model) -> None:
    images, mask = _inputs(k=5)
    perm = torch.tensor([3, 0, 4, 2, 1])
    with torch.no_grad():
        a = test_model(images, mask)
        b = test_model(images[:, perm], mask)
    assert torch.allclose(a, b, atol=1e-5)
    # The model does look at the images: changing one changes the output.
    images2 = images.clone()
    images2[:, 0] = images2[:, 0].flip(-1)
    with torch.no_grad():
        c = test_model(images2, mask)
    assert (a - c).abs().max() > 1e-3


@pytest.mark.parametrize("k", [1, 2, 3, 4, 5])
def test_any_number_of_images(test_model, k: int) -> None:
    images, mask = _inputs(k=k)
    with torch.no_grad():
        out = test_model(images, mask)
    norms = out.norm(dim=1)[mask[:, 0] > 0]
    assert torch.allclose(norms, torch.ones_like(norms), atol=1e-5)


def test_chunked_decoding_equals_unchunked(test_model) -> None:
    images, mask = _inputs(b=2, k=3, h=40, w=40)
    small = create_model("glc-test", pixel_chunk=7).eval()
    small.load_state_dict(test_model.state_dict())
    with torch.no_grad():
        a = test_model(images, mask)  # pixel_chunk 4096 > 1600 pixels: one chunk
        b = small(images, mask)
    assert torch.allclose(a, b, atol=1e-6)


def test_decode_pixels_matches_forward_at_pixel_centres(test_model) -> None:
    images, mask = _inputs(b=1, k=4, h=36, w=36)
    ys, xs = torch.nonzero(mask[0, 0] > 0, as_tuple=True)
    ys, xs = ys[::17], xs[::17]
    coords = pixel_centre_coords(ys, xs, 36, 36)[None]  # (1, N, 2)
    with torch.no_grad():
        full = test_model(images, mask)
        ctx = test_model.encode(images, mask)
        sampled = test_model.decode_pixels(ctx, images, mask, coords)  # (1, N, 3)
    assert torch.allclose(sampled[0], full[0][:, ys, xs].T, atol=1e-5)


def test_uniform_context_is_spatially_constant() -> None:
    torch.manual_seed(0)
    model = create_model("glc-test", uniform_context=True).eval()
    images, mask = _inputs(k=3)
    with torch.no_grad():
        ctx = model.encode(images, mask)  # (1, 3, C, 8, 8)
    flat = ctx.flatten(-2)
    assert torch.allclose(flat, flat[..., :1].expand_as(flat), atol=0)
    # Still differs between images (they saw different lighting), and equals the masked mean of
    # the spatially varying contexts of the same weights.
    assert (ctx[0, 0] - ctx[0, 1]).abs().max() > 1e-4
    plain = create_model("glc-test").eval()
    plain.load_state_dict(model.state_dict())
    with torch.no_grad():
        varying = plain.encode(images, mask)
    assert varying.flatten(-2).std(-1).max() > 1e-4
    m = torch.nn.functional.adaptive_avg_pool2d(mask, (8, 8)).reshape(1, 1, 1, 8, 8)
    expected = (varying * m).sum((-2, -1)) / m.sum((-2, -1))
    assert torch.allclose(ctx[..., 0, 0], expected, atol=1e-5)


def test_bad_names_and_options_raise() -> None:
    with pytest.raises(ValueError, match="glc-nope.*known models.*glc-tiny"):
        create_model("glc-nope")
    with pytest.raises(ValueError, match="'context_dims'"):
        create_model("glc-test", context_dims=8)
    with pytest.raises(ValueError, match="canonical_resolution"):
        create_model("glc-test", canonical_resolution=48)
    with pytest.raises(ValueError, match="decoder_heads"):
        create_model("glc-test", decoder_heads=3)
    # One base class (unips.models.config_base.ModelConfig) gives every config the same one-line errors.
    from unips.models import SDMConfig, UniPS22Config

    for make, message in ((lambda: create_model("glc-test", decoder_heads=0), "GLCConfig.decoder_heads=0: "),
                          (lambda: UniPS22Config(heads=0), "UniPS22Config.heads=0: expected a positive integer"),
                          (lambda: SDMConfig(dropout=1.0), r"SDMConfig.dropout=1.0: expected a probability in \["),
                          (lambda: SDMConfig(ppm_scales=[]), r"SDMConfig.ppm_scales=\(\): expected positive pooled")):
        with pytest.raises(ValueError, match="^" + message):
            make()
    assert UniPS22Config(swin_depths=[2, 2, 18, 2]) == UniPS22Config()  # JSON lists back to tuples


def test_each_entry_carries_its_input_contract() -> None:
    from unips.inference import DEFAULT_TTA, TTA_VIEWS
    from unips.models import DEFAULT_MODEL, DEFAULT_TRAIN_MODEL, InputContract, input_contract, list_pretrained
    from unips.models.contract import UNIPS_INPUTS, VIEWS

    assert DEFAULT_MODEL in list_pretrained() and DEFAULT_TRAIN_MODEL in list_models()
    assert TTA_VIEWS == VIEWS and DEFAULT_TTA == UNIPS_INPUTS.views
    assert input_contract("glc-test") == UNIPS_INPUTS and input_contract(DEFAULT_MODEL).train_resolution == 128
    glc, sdm = input_contract("glc-unips"), input_contract("sdm-unips-tiny")
    assert (glc.preprocess, glc.side, glc.max_images, glc.views, glc.patch) == ("glc-unips", 512, 64, 1, None)
    assert (sdm.preprocess, sdm.margin, sdm.max_images, sdm.views, sdm.patch) == ("sdm-unips", 8, 10, 1, 512)
    with pytest.raises(ValueError, match=r"^InputContract.views=3: expected one of 1, 2, 4, 8$"):
        InputContract(views=3)


def test_bad_inputs_raise(test_model) -> None:
    images, mask = _inputs()
    with pytest.raises(ValueError, match="images"):
        test_model(images[0], mask)
    with pytest.raises(ValueError, match="mask"):
        test_model(images, mask[:, :, :16])
    with pytest.raises(ValueError, match="coords"):
        test_model.decode_pixels(test_model.encode(images, mask), images, mask, torch.zeros(1, 5, 3))


def test_create_model_loads_shipped_weights_or_a_file_never_fresh_ones(tmp_path) -> None:
    """One `create_model(name, pretrained=..., checkpoint_path=...)`: the registry's pretrained entry, a model
    file of that model, or fresh weights; the weights' model must be the name asked for."""
    from unips.models import DEFAULT_MODEL, load_model, pretrained_weights, save_checkpoint

    shipped = create_model(DEFAULT_MODEL, pretrained=True)
    reference, meta = load_model(pretrained_weights(DEFAULT_MODEL))
    assert not shipped.training and meta["model_name"] == DEFAULT_MODEL
    assert all(torch.equal(a, b) for a, b in zip(shipped.state_dict().values(), reference.state_dict().values()))
    torch.manual_seed(3)
    saved = save_checkpoint(tmp_path / "t.safetensors", create_model("glc-test"))
    loaded = create_model("glc-test", checkpoint_path=saved)
    assert not loaded.training and loaded.model_name == "glc-test"
    with pytest.raises(ValueError, match="holds model 'glc-test', not 'glc-tiny'"):
        create_model("glc-tiny", checkpoint_path=saved)
    with pytest.raises(ValueError, match="not allowed with weights"):
        create_model(DEFAULT_MODEL, pretrained=True, dropout=0.0)
    with pytest.raises(FileNotFoundError, match="model file .* does not exist"):
        create_model("glc-test", checkpoint_path=tmp_path / "missing.safetensors")


def test_config_round_trips_through_json() -> None:
    model = create_model("glc-tiny", uniform_context=True)
    d = json.loads(json.dumps(dataclasses.asdict(model.config)))
    assert GLCConfig(**d) == model.config
    rebuilt = create_model("glc-tiny", **d)
    assert rebuilt.config == model.config
    assert [p.shape for p in rebuilt.parameters()] == [p.shape for p in model.parameters()]


_MEMORY_SCRIPT = textwrap.dedent("""
    import sys, torch
    from unips.models import create_model
    res, chunk = int(sys.argv[1]), int(sys.argv[2])
    torch.set_num_threads(1)
    torch.manual_seed(0)
    model = create_model("glc-test", pixel_chunk=chunk).eval()
    images, mask = torch.rand(1, 8, 3, res, res), torch.ones(1, 1, res, res)
    with torch.no_grad():
        model(images[..., :32, :32], mask[..., :32, :32])  # warm up kernels and allocator
    def status_kib(key):
        with open("/proc/self/status") as f:
            return next(int(line.split()[1]) for line in f if line.startswith(key + ":"))
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")  # reset the peak-RSS mark (VmHWM) to the current RSS
    base = status_kib("VmRSS")
    with torch.no_grad():
        out = model(images, mask)
    print((status_kib("VmHWM") - base) / 1024)
""")


def _extra_peak_mib(res: int, chunk: int) -> float:
    out = subprocess.run([sys.executable, "-c", _MEMORY_SCRIPT, str(res), str(chunk)], cwd=REPO,
                         capture_output=True, text=True, timeout=120, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def test_prediction_memory_is_bounded_by_chunking() -> None:
    """Extra peak memory of a forward pass (inputs already allocated) barely grows with resolution."""
    at_256 = _extra_peak_mib(256, 2048)
    at_512 = _extra_peak_mib(512, 2048)
    unchunked_256 = _extra_peak_mib(256, 10 ** 7)
    print(f"extra peak MiB: chunked 256 {at_256:.1f}, 512 {at_512:.1f}; unchunked 256 {unchunked_256:.1f}")
    # 4x the pixels: full-resolution copies of the 8 input images and the output may grow (per added pixel
    # (8 x 3 + 3) float32: 20 MiB from 256 to 512), the decoder working set must not (unchunked it is
    # ~340 MiB at 256 and would be 4x that at 512). The RSS peak moves by ~6 MiB between runs (allocator).
    grown_pixels_mib = (512 ** 2 - 256 ** 2) * (8 * 3 + 3) * 4 / 2 ** 20
    assert at_512 < at_256 + grown_pixels_mib + 8
    # Control: the measurement does see the decoder's working set when it is not chunked.
    assert unchunked_256 > 4 * at_512
