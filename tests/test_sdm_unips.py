"""SDM-UniPS: our network against the authors' code (the test oracle in ../shared/reference, skipped without it),
their checkpoint format read through our loader, and the one-line refusals of bad checkpoints.

The authors' network is built with seeded random weights, saved as their code saves it (the state dict of the
`DataParallel`-wrapped network, `module.` prefixes, in `normal/*.pytmodel`), read through `create_model`, and
both networks run on the same tiny input (canonical 32, 64 x 64 px: the published code takes both at run time).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch
from fixtures import SHARED, write_synthetic_object
from published import angle_deg, load_error, randomise, reference_module

from unips.models import convert_official, create_model, list_models
from unips.models.sdm import gaussian_blur
from unips.models.sdm_encoder import merge_interleaved, split_interleaved

REFERENCE = SHARED / "reference" / "SDM-UniPS-CVPR2023" / "sdm_unips" / "modules"
ALIAS = "sdm_unips_reference"  # the authors' package is named `modules`: imported under a name of its own
CANONICAL, SIDE, IMAGES, PIXELS = 32, 64, 2, 128  # PIXELS: chunks of the pixel-sampling transformer


def _reference(module: str):
    """A module of the authors' code (`model.model`, `utils.gauss_filter`, ...); skips without it."""
    if REFERENCE.is_dir():
        pytest.importorskip("einops", reason="the reference code imports einops (pip install -e '.[test]')")
    return reference_module(REFERENCE, ALIAS, module)


def _save_official(state: dict[str, torch.Tensor], folder: Path) -> Path:
    """`state` as the published checkpoint holds it: `folder/normal/nml.pytmodel`, keys `module.*`."""
    (folder / "normal").mkdir(parents=True, exist_ok=True)
    torch.save({f"module.{k}": v for k, v in state.items()}, folder / "normal" / "nml.pytmodel")
    return folder


def _inputs(side: int = SIDE, k: int = IMAGES, radius: float = 10.5) -> tuple[torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(1)
    images = torch.rand(1, k, 3, side, side, generator=g) * 2  # (1, K, 3, H, W)
    yy, xx = torch.meshgrid(torch.arange(side), torch.arange(side), indexing="ij")
    mask = (((yy - side / 2) ** 2 + (xx - side / 2 + 3) ** 2) < radius ** 2).float()
    return images, mask[None, None]


@pytest.fixture(scope="module")
def official(tmp_path_factory):
    """(the authors' network with seeded weights in eval mode, its checkpoint folder)."""
    ref = _reference("model.model")
    net = ref.Net(PIXELS, "normal", torch.device("cpu"))
    randomise(net, seed=0)
    folder = tmp_path_factory.mktemp("sdm_official")
    torch.save(torch.nn.DataParallel(net).state_dict(), _save_official({}, folder) / "normal" / "nml.pytmodel")
    return net.eval(), folder


@pytest.fixture(scope="module")
def ours(official):
    _, folder = official
    return create_model("sdm-unips", checkpoint_path=folder, canonical_resolution=CANONICAL, pixel_samples=PIXELS)


def test_registry_has_the_published_and_the_tiny_network() -> None:
    assert {"sdm-unips", "sdm-unips-tiny"} <= set(list_models())
    assert 100_000 < create_model("sdm-unips-tiny").num_parameters() < 300_000


def test_normal_maps_equal_the_reference(official, ours) -> None:
    """The whole network: encoder at 2 x 2 interleaved tiles, smoothing, 3 chunks of shuffled pixels."""
    net, _ = official
    images, mask = _inputs()
    assert int(mask.sum()) > 2 * PIXELS  # several chunks: the pixel-sampling transformer's split is compared too
    with torch.no_grad():
        np.random.seed(7)  # the published decoder shuffles the pixels with numpy's global generator
        theirs = net(images.permute(0, 2, 3, 4, 1), mask, torch.tensor([[IMAGES]]),
                     decoder_resolution=torch.full((1, 1), SIDE), canonical_resolution=torch.full((1, 1), CANONICAL))[0]
        mine = ours(images, mask, rng=np.random.RandomState(7))
    inside = mask[:, 0] > 0
    assert torch.equal(mine.norm(dim=1)[~inside], torch.zeros_like(mine.norm(dim=1)[~inside]))
    diff = (mine - theirs * mask).abs().max().item()
    angle = angle_deg(mine, theirs)[inside].max().item()
    print(f"\nsdm-unips vs reference: max |normal difference| {diff:.2e}, max angle {angle:.2e} deg")
    assert diff < 1e-4 and angle < 0.01


def test_encoder_contexts_equal_the_reference_without_tiles(official, ours) -> None:
    """The scale-invariant encoder alone when the input is at the canonical side (one tile: the contexts are
    those of the resized image, added twice)."""
    net, _ = official
    images, mask = _inputs(side=CANONICAL, radius=10)
    x = torch.cat([images[0] * mask, mask.expand(IMAGES, 1, CANONICAL, CANONICAL)], dim=1)  # (K, 4, H, W)
    with torch.no_grad():
        theirs = net.image_encoder(x, torch.tensor([IMAGES]), CANONICAL)
        mine = ours.image_encoder(x, IMAGES)
    assert (mine - theirs).abs().max().item() < 1e-5 * theirs.abs().max().item()


def test_interleaved_tiles_equal_the_reference() -> None:
    """3 x 3 interleaved tiles out and back in, against the published unfold / fold."""
    ref = _reference("model.decompose_tensors")
    x = torch.randn(2, 4, 12, 12)
    tiles = split_interleaved(x, 4)  # (9 * 2, 4, 4, 4)
    theirs = ref.divide_tensor_spatial(x, block_size=4, method="tile_stride")  # (2, 9, 4, 4, 4)
    assert torch.equal(tiles, theirs.permute(1, 0, 2, 3, 4).reshape(18, 4, 4, 4))
    assert torch.equal(merge_interleaved(tiles, 3), ref.merge_tensor_spatial(tiles.reshape(9, 2, 4, 4, 4)))
    assert torch.equal(merge_interleaved(tiles, 3), x)


def test_pixel_decoder_blocks_equal_the_reference(official, ours) -> None:
    """Per-pixel blocks on random tokens, and the pixel-sampling transformer over 1100 pixels (two query
    buckets of the published memory-efficient attention)."""
    net, _ = official
    g = torch.Generator().manual_seed(2)
    tokens = torch.randn(100, IMAGES, 259, generator=g)  # (pixels, images, RGB + context)
    features = torch.randn(1100, 384, generator=g)  # (pixels, aggregated)
    with torch.no_grad():
        up = net.glc_upsample(tokens)
        x = torch.cat([tokens[..., :3], up], dim=2)
        pairs = [(up, ours.glc_upsample(tokens)), (net.glc_aggregation(x), ours.glc_aggregation(x)),
                 (net.regressor(features, len(features))[0], ours.regressor(features))]
    for theirs, mine in pairs:
        assert (mine - theirs).abs().max().item() < 1e-5 * max(1.0, theirs.abs().max().item())


def test_context_smoothing_equals_the_reference() -> None:
    gauss = _reference("utils.gauss_filter")
    x = torch.randn(2, 5, 16, 16)
    assert torch.allclose(gaussian_blur(x, 21), gauss.gauss_filter(5, 21, 1)(x), atol=1e-6)


# -- checkpoint files (the tiny network: its files have the published layout at its own size) -----------------

@pytest.fixture(scope="module")
def tiny_state() -> dict[str, torch.Tensor]:
    torch.manual_seed(0)
    return dict(create_model("sdm-unips-tiny").state_dict())


def test_conversion_round_trip(tiny_state, tmp_path) -> None:
    folder = _save_official(tiny_state, tmp_path / "ckpt")
    model = create_model("sdm-unips-tiny", checkpoint_path=folder)
    same = create_model("sdm-unips-tiny", checkpoint_path=folder / "normal" / "nml.pytmodel")
    out = convert_official("sdm-unips-tiny", folder, tmp_path / "sdm-tiny.safetensors")
    again = create_model("sdm-unips-tiny", checkpoint_path=out)
    assert not model.training
    for m in (model, same, again):
        assert all(torch.equal(v, tiny_state[k]) for k, v in m.state_dict().items())
    images, mask = _inputs()
    with torch.no_grad():
        assert torch.equal(model(images, mask), again(images, mask))


def _one_line_error(folder: Path, name: str = "sdm-unips-tiny") -> str:
    return load_error(folder, name)


def test_missing_or_ambiguous_files_are_one_line(tiny_state, tmp_path) -> None:
    (tmp_path / "empty").mkdir()
    assert "no file matching 'normal/*.pytmodel'" in _one_line_error(tmp_path / "empty")
    folder = _save_official(tiny_state, tmp_path / "two")
    torch.save({}, folder / "normal" / "other.pytmodel")
    assert "2 files" in _one_line_error(folder)
    assert "has no published checkpoint format" in _one_line_error(folder, name="glc-test")


def test_mismatched_tensors_are_one_line_naming_them(tiny_state, tmp_path) -> None:
    removed = dict(tiny_state)
    del removed["regressor.prediction_normal.regression.2.bias"]
    assert "missing tensors regressor.prediction_normal.regression.2.bias;" in _one_line_error(
        _save_official(removed, tmp_path / "removed"))
    extra = dict(tiny_state, **{"regressor.prediction_base.regression.0.weight": torch.zeros(8, 16)})
    assert "unexpected tensors regressor.prediction_base.regression.0.weight" in _one_line_error(
        _save_official(extra, tmp_path / "extra"))
    wrong = dict(tiny_state, **{"glc_aggregation.aggregation.dec.0.S": torch.zeros(1, 1, 8)})
    assert "glc_aggregation.aggregation.dec.0.S has shape 1x1x8" in _one_line_error(
        _save_official(wrong, tmp_path / "wrong"))


def test_unreadable_files_are_one_line(tmp_path) -> None:
    (tmp_path / "bad" / "normal").mkdir(parents=True)
    (tmp_path / "bad" / "normal" / "nml.pytmodel").write_bytes(b"not a checkpoint")
    assert "not a readable checkpoint of tensors" in _one_line_error(tmp_path / "bad")
    (tmp_path / "list" / "normal").mkdir(parents=True)
    torch.save([torch.zeros(1)], tmp_path / "list" / "normal" / "nml.pytmodel")
    assert "expected a state dict" in _one_line_error(tmp_path / "list")


# -- the published preprocessing and the prediction CLI ------------------------------------------------------

def _object_folder(tmp_path: Path, hole: int = 0) -> Path:
    """An 80 x 80 px object of 3 noisy 16-bit images (a disk mask, with a hole of radius `hole`: fewer pixels to
    decode) in our layout, which the published loader reads too (L*.png, mask.png, normal.tif)."""
    yy, xx = np.mgrid[:80, :80]
    mask = (hole ** 2 <= (yy - 40) ** 2 + (xx - 38) ** 2) & ((yy - 40) ** 2 + (xx - 38) ** 2 < 25 ** 2)
    images = (np.random.default_rng(0).random((3, 80, 80, 3)) * 0.8).astype(np.float32)
    normals = np.zeros((80, 80, 3), np.float32)
    normals[..., 2] = 1
    return write_synthetic_object(tmp_path / "obj.data", images, mask, normals)


def test_preprocessing_equals_the_reference_loader(tmp_path) -> None:
    """Crop, working side, mask and normalised images against the published data loader (same image order)."""
    from unips.data import load_object
    from unips.sdm_preprocess import sdm_crop, sdm_inputs

    loader = _reference("io.dataloader.realdata").dataloader(10, outdir=str(tmp_path / "ref"), mask_margin=8)
    folder = _object_folder(tmp_path)
    np.random.seed(3)  # the published loader draws the order of the images
    loader.load(str(folder), prefix="L*", max_image_resolution=4096)
    order = np.random.RandomState(3).permutation(3)
    obj = load_object(folder)
    crop = sdm_crop(obj.mask)
    images, mask = sdm_inputs(obj, crop)
    assert [crop.r0, crop.r1, crop.c0, crop.c1] == list(loader.roi[2:]) and crop.side == loader.h == 512
    assert np.array_equal(mask, loader.mask[..., 0])
    assert np.abs(images[order] - loader.I.transpose(3, 0, 1, 2)).max() < 1e-4  # 16-bit files: rounding only


def test_predict_cli_runs_published_weights(tiny_state, tmp_path, capsys) -> None:
    from unips.predict import main

    folder = _object_folder(tmp_path)
    ckpt = _save_official(tiny_state, tmp_path / "ckpt")
    out = tmp_path / "pred"
    assert main(["--method", "model", "--model", "sdm-unips-tiny", "--checkpoint", str(ckpt), "--input", str(folder),
                 "--out", str(out), "--res", "128"]) == 0
    info = json.loads((out / "obj" / "predict.json").read_text())
    assert info["model_name"] == "sdm-unips-tiny" and info["tta"] == 1
    capsys.readouterr()
    # A folder of published weights without --model, and a checkpoint with a tensor missing: one line each.
    for flags, words in ((["--checkpoint", str(ckpt)], "--model"),
                         (["--model", "sdm-unips-tiny", "--checkpoint", str(_save_official(
                             {k: v for k, v in tiny_state.items() if "regressor" not in k}, tmp_path / "part"))],
                          "missing tensors regressor.")):
        assert main(["--method", "model", *flags, "--input", str(folder), "--out", str(tmp_path / "p2")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("error: ") and words in err[0]


# -- --scalable: the working image as interleaved sub-images ---------------------------------------------------

PATCH, TILED_SIDE = 64, 128  # the published patch is 512 (canonical 256); the same ratio here at canonical 32


def _official_builder(patch: int = PATCH):
    """The authors' `builder` module (their `main.py` prediction loop), its literal 512 px patch replaced by `patch`
    and its `cv2.imwrite` replaced by a recorder (`module.written[name]`: the float array it would have saved)."""
    import types

    import cv2

    _reference("model.model")  # registers the package the builder's imports are redirected to
    path = REFERENCE / "builder" / "builder.py"
    source = path.read_text()
    assert source.count("patch_size = 512") == 1, "the reference builder changed: its patch size is not found"
    source = source.replace("from modules.", f"from {ALIAS}.").replace("patch_size = 512", f"patch_size = {patch}")
    module = types.ModuleType(f"{ALIAS}.scalable_builder")
    exec(compile(source, str(path), "exec"), module.__dict__)
    module.written = {}
    module.cv2 = types.SimpleNamespace(resize=cv2.resize, INTER_CUBIC=cv2.INTER_CUBIC,
                                       imwrite=lambda name, a: module.written.__setitem__(Path(name).name, a.copy()))
    return module


class _Prepared(torch.utils.data.Dataset):
    """One object as the authors' data loader hands it to their builder (already preprocessed)."""

    def __init__(self, images: np.ndarray, mask: np.ndarray, crop, frame: tuple[int, int], workspace: Path) -> None:
        import types

        self.item = (images.transpose(3, 1, 2, 0), np.zeros((3,) + mask.shape, np.float32), mask[None],
                     len(images), np.array([*frame, crop.r0, crop.r1, crop.c0, crop.c1]))
        self.data = types.SimpleNamespace(h=mask.shape[0], data_workspace=str(workspace), objname="obj")
        self.max_image_resolution = None

    def __getitem__(self, index: int):
        return self.item

    def __len__(self) -> int:
        return 1


def _against_builder(official_folder: Path, obj, side: int, patch: int | None, canonical: int, pixels: int,
                     workspace: Path, model=None) -> tuple[float, float]:
    """(max |normal difference|, max angle in deg inside the mask) between the authors' builder run (`--scalable`
    with `patch`, or the whole image at once when None) and `run_published` on `obj` at working side `side` (our
    network `model`, default: read from `official_folder`)."""
    import types

    from unips.inference import LoadedModel, run_published
    from unips.models import create_model
    from unips.sdm_preprocess import sdm_crop, sdm_inputs

    crop = sdm_crop(obj.mask)
    crop = type(crop)(crop.r0, crop.r1, crop.c0, crop.c1, side)
    images, mask = sdm_inputs(obj, crop)
    module = _official_builder(patch or PATCH)
    args = types.SimpleNamespace(target="normal", checkpoint=str(official_folder), pixel_samples=pixels,
                                 canonical_resolution=canonical, scalable=patch is not None)
    runner = module.builder(args, torch.device("cpu"))
    np.random.seed(5)
    runner.run(canonical_resolution=canonical, testdata=_Prepared(images, mask, crop, obj.mask.shape, workspace),
               max_image_resolution=4096)
    theirs = (module.written["normal.png"] / 127.5 - 1)[:, :, ::-1]  # 255 * (1 + n) / 2 in BGR order
    model = model or create_model("sdm-unips", checkpoint_path=official_folder, canonical_resolution=canonical,
                         pixel_samples=pixels)
    net = LoadedModel(model=model, meta={"model_name": "sdm-unips"}, checkpoint=official_folder, device="cpu")
    mine = run_published(net, obj, res=side, patch=patch, rng=np.random.RandomState(5))
    both = torch.from_numpy(np.ascontiguousarray(np.stack([mine, theirs]).transpose(0, 3, 1, 2)))
    assert np.abs(theirs[obj.mask]).max() > 0.1  # a map, not an empty frame
    return float(np.abs(mine - theirs).max()), angle_deg(both[:1], both[1:])[0][torch.from_numpy(obj.mask)].max().item()


def test_scalable_prediction_equals_the_reference(official, ours, tmp_path) -> None:
    """`run_published(..., patch=PATCH)` against the authors' `--scalable` run (their builder's loop, their
    post-processing) on a 128 px working image: 4 sub-images of 64 px, each in 2 x 2 tiles of the canonical 32 and
    several chunks of pixels of a ring (the same shuffles: one generator shared by the sub-images in turn)."""
    from unips.data import load_object

    obj = load_object(_object_folder(tmp_path, hole=21))
    diff, angle = _against_builder(official[1], obj, TILED_SIDE, PATCH, CANONICAL, PIXELS, tmp_path, ours)
    print(f"\n--scalable vs reference: max |normal difference| {diff:.2e}, max angle {angle:.2e} deg")
    assert diff < 1e-4 and angle < 0.01


def _dots_object(tmp_path: Path, k: int):
    """`k` images of 5 isolated pixels spanning 50 px of an 80 px frame: a full-size working image with few pixels
    to decode."""
    from unips.data import load_object

    mask = np.zeros((80, 80), bool)
    mask[[15, 15, 65, 65, 40], [15, 65, 15, 65, 40]] = True
    images = (np.random.default_rng(0).random((k, 80, 80, 3)) * 0.8).astype(np.float32)
    normals = np.zeros((80, 80, 3), np.float32)
    normals[..., 2] = 1
    return load_object(write_synthetic_object(tmp_path / "dots.data", images, mask, normals))


@pytest.mark.slow
@pytest.mark.parametrize("side, patch, k", [(512, None, 2), (1024, 512, 1)], ids=["whole-512", "scalable-1024"])
def test_full_size_prediction_equals_the_reference(official, tmp_path, side, patch, k) -> None:
    """The published shape end to end: canonical 256, 10000-pixel chunks; the whole 512 px working image of 2
    images, and `--scalable` on a 1024 px one with the authors' own 512 px patch (4 sub-images; 1 image: with 2 it
    takes 3 minutes). About 50 and 110 s on 2 CPU cores (the encoder: ConvNeXt-T on 5 tiles of 256 px per image and
    sub-image, on both sides)."""
    diff, angle = _against_builder(official[1], _dots_object(tmp_path, k), side, patch, 256, 10000, tmp_path)
    print(f"\nfull size {side} px, patch {patch}: max |normal difference| {diff:.2e}, max angle {angle:.2e} deg")
    assert diff < 1e-4 and angle < 0.01


def test_scalable_skips_sub_images_without_object() -> None:
    from unips.sdm_preprocess import scalable_forward

    calls = []

    def model(images, mask, rng):
        calls.append(tuple(images.shape))
        return mask.expand(-1, 3, -1, -1) * images[:, 0]

    images, mask = torch.rand(1, 2, 3, 8, 8), torch.zeros(1, 1, 8, 8)
    mask[..., 1::2, 0::2] = 1  # only the sub-image at offset (1, 0)
    out = scalable_forward(model, images, mask, patch=4)
    assert calls == [(1, 2, 3, 4, 4)]
    assert torch.equal(out, mask.expand(-1, 3, -1, -1) * images[:, 0])
    with pytest.raises(ValueError, match="patch: 3 does not divide the working side 8"):
        scalable_forward(model, images, mask, patch=3)


def test_predict_cli_scalable_and_its_refusals(tiny_state, tmp_path, capsys, monkeypatch) -> None:
    """`--scalable` runs (at --res 512: one sub-image, the several of a larger side are compared with the reference
    above at a smaller patch); misuse and a run that would not fit are one line
    naming the flag, before any prediction."""
    from scenes.cli import limits
    from unips.inference import prediction_memory
    from unips.predict import main

    folder = _object_folder(tmp_path)
    ckpt = _save_official(tiny_state, tmp_path / "ckpt")
    run = ["--method", "model", "--model", "sdm-unips-tiny", "--checkpoint", str(ckpt), "--input", str(folder)]
    assert main([*run, "--out", str(tmp_path / "pred"), "--res", "512", "--scalable"]) == 0
    info = json.loads((tmp_path / "pred" / "obj" / "predict.json").read_text())
    assert info["scalable"] is True and info["resolution"] == 512
    capsys.readouterr()

    def refused(flags: list[str], words: str) -> str:
        assert main([*flags, "--out", str(tmp_path / "p2")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("error: ") and words in err[0], err
        return err[0]

    refused(
        ["--method", "least-squares", "--input", str(folder), "--scalable"], "--scalable: only used with --method model"
    )
    refused([*run[:2], "--model", "glc-test", *run[4:], "--scalable"], "--scalable: only for the SDM-UniPS networks")
    refused([*run, "--res", "768", "--scalable"], "--res 768: --scalable needs a multiple of its 512 px sub-images")
    whole = prediction_memory("model", (80, 80), 3, 1024, 1, inputs="sdm-unips")
    tiled = prediction_memory("model", (80, 80), 3, 1024, 1, inputs="sdm-unips", patch=512)
    assert tiled < whole / 2
    monkeypatch.setattr(limits, "available_memory", lambda: (whole + tiled) // 2)
    line = refused([*run, "--res", "1024"], "--res: --method model on obj (3 images of 80 x 80 px")
    assert "add --scalable (512 px sub-images" in line
    monkeypatch.setattr(limits, "available_memory", lambda: tiled - 1)
    line = refused([*run, "--res", "1024", "--scalable"], "--scalable: --method model on obj")
    assert "in 4 sub-images of 512 px (--scalable)" in line and "lower --res or --max-images" in line
