"""glc-unips, the published UniPS (CVPR 2022): our network against the authors' code (the test oracle in
../shared/reference, skipped without it), their checkpoint files read through our loader, the one-line refusals of
bad checkpoints, and their preprocessing.

The authors' network is built with seeded random weights and saved by their own code (`Net.save_models`: the state
dicts of the `DataParallel`-wrapped encoder, aggregation and prediction in `*_enc`, `*_agg`, `*_pred.pytmodel`, with
optimizer and scheduler files beside them), read through `create_model`, and both run on the same tiny input:
encoder side 32, decoder side 64 (the published code takes both at run time), 2 images.
"""

from __future__ import annotations

import json
import types
from pathlib import Path

import numpy as np
import pytest
import torch
from fixtures import SHARED, write_synthetic_object
from published import angle_deg, load_error, randomise, reference_module

from unips.models import convert_official, create_model, list_models

REFERENCE = SHARED / "reference" / "Universal-PS-CVPR2022" / "source" / "modules"
ALIAS = "unips22_reference"  # the authors' package is named `modules`: imported under a name of its own
CANONICAL, SIDE, IMAGES = 32, 64, 2
PARTS = ("enc", "agg", "pred")  # the published files, and our state-dict prefixes below
PREFIX = {"enc": "encoder.", "agg": "aggregation.", "pred": "prediction."}
# The reference code imports timm's old module path.
pytestmark = pytest.mark.filterwarnings("ignore:Importing from timm.models.layers:FutureWarning")


def _reference(module: str):
    return reference_module(REFERENCE, ALIAS, module)


def _inputs(side: int = SIDE, k: int = IMAGES, radius: float = 20.5) -> tuple[torch.Tensor, torch.Tensor]:
    """Masked images `(1, K, 3, side, side)` (as the published loader gives them) and a disk mask."""
    g = torch.Generator().manual_seed(1)
    images = torch.rand(1, k, 3, side, side, generator=g) * 2
    yy, xx = torch.meshgrid(torch.arange(side), torch.arange(side), indexing="ij")
    mask = (((yy - side / 2) ** 2 + (xx - side / 2 + 3) ** 2) < radius ** 2).float()[None, None]
    return images * mask[:, None], mask


@pytest.fixture(scope="module")
def official(tmp_path_factory):
    """(the authors' network with seeded weights in test mode, its checkpoint folder as their code writes it)."""
    ref = _reference("model.model")
    args = types.SimpleNamespace(min_nimg=2, num_samples=2500, session_name="ref", num_agg_enc=3,
                                 agg_type="Transformer", lr=1e-4, lr_scheduler="step")  # main.py's defaults
    torch.manual_seed(0)
    net = ref.Net(args, torch.device("cpu"))
    for i, part in enumerate((net.encoder, net.aggregation, net.prediction)):
        randomise(part, seed=i)
    folder = tmp_path_factory.mktemp("glc_official")
    net.save_models(str(folder))
    net.set_mode("Test")
    return net, folder


@pytest.fixture(scope="module")
def ours(official):
    return create_model("glc-unips", checkpoint_path=official[1], canonical_resolution=CANONICAL)


def _their_normals(net, images: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """The published test step's normal map at the decoder side `(1, 3, H, W)`. The step returns only a picture
    (both resolutions side by side, upsampled), so its prediction head's outputs are caught: the first call is the
    encoder-side map, the next ones the decoder-side chunks of the masked pixels in index order."""
    side = images.shape[-1]
    outs: list[torch.Tensor] = []
    hook = net.prediction.register_forward_hook(lambda module, inp, out: outs.append(out))
    try:
        with torch.no_grad():
            net.step((images.permute(0, 2, 3, 4, 1), torch.zeros(1, 3, side, side), mask),
                     decoder_imgsize=(side, side), encoder_imgsize=(CANONICAL, CANONICAL))
    finally:
        hook.remove()
    ids = torch.nonzero(mask.reshape(-1) > 0)[:, 0]
    normals = torch.zeros(3, side * side)
    normals[:, ids] = torch.nn.functional.normalize(torch.cat(outs[1:]), dim=1).T
    return normals.reshape(1, 3, side, side)


def test_registry_has_the_published_and_the_tiny_network() -> None:
    assert {"glc-unips", "glc-unips-tiny"} <= set(list_models())
    assert 66e6 < create_model("glc-unips").num_parameters() < 72e6  # the paper: about 69 M
    assert 50_000 < create_model("glc-unips-tiny").num_parameters() < 300_000


def test_normal_maps_equal_the_reference(official, ours) -> None:
    """The whole network from the authors' own files: Swin-S maps of 8 .. 1 px padded to windows of 7, attention
    across the images, fusion, and every masked pixel decoded at twice the encoder side."""
    net, _ = official
    images, mask = _inputs()
    theirs = _their_normals(net, images, mask)
    with torch.no_grad():
        mine = ours(images, mask)
    inside = mask[:, 0] > 0
    assert torch.equal(mine.norm(dim=1)[~inside], torch.zeros_like(mine.norm(dim=1)[~inside]))
    diff = (mine - theirs).abs().max().item()
    angle = angle_deg(mine, theirs)[inside].max().item()
    print(f"\nglc-unips vs reference: max |normal difference| {diff:.2e}, max angle {angle:.2e} deg")
    assert diff < 1e-4 and angle < 0.01


def test_swin_backbone_equals_the_reference_on_odd_maps() -> None:
    """Our Swin against the authors' at a small width with windows of 4 on a 48 px input: maps of 12, 6, 3 and
    2 px (padding to whole windows, an odd map merged), the state dict loaded across by name."""
    from unips.models.swin import SwinBackbone

    ref = _reference("model.utils.folked.swin_transformer")
    theirs = ref.SwinTransformer(in_chans=4, embed_dim=8, depths=[1, 2, 1, 1], num_heads=[1, 2, 2, 4], window_size=4)
    randomise(theirs, seed=3)
    mine = SwinBackbone(4, 8, (1, 2, 1, 1), (1, 2, 2, 4), window=4, drop_path=0.2)
    mine.load_state_dict(theirs.state_dict(), strict=True)
    x = torch.randn(2, 4, 48, 48, generator=torch.Generator().manual_seed(4))
    theirs.eval()  # returns None there (its train() override returns nothing)
    with torch.no_grad():
        pairs = list(zip(mine.eval()(x), theirs(x)))
    assert [tuple(m.shape[2:]) for m, _ in pairs] == [(12, 12), (6, 6), (3, 3), (2, 2)]
    for m, t in pairs:
        assert m.shape == t.shape and (m - t).abs().max().item() < 1e-5


# -- checkpoint files (the tiny network: its files have the published layout at its own size) -----------------

@pytest.fixture(scope="module")
def tiny_state() -> dict[str, torch.Tensor]:
    torch.manual_seed(0)
    return dict(create_model("glc-unips-tiny").state_dict())


def _save_official(state: dict[str, torch.Tensor], folder: Path, parts: tuple[str, ...] = PARTS) -> Path:
    """`state` split as the published files hold it: `folder/tiny_{part}.pytmodel`, keys `module.*`."""
    folder.mkdir(parents=True, exist_ok=True)
    for part in parts:
        torch.save({f"module.{k[len(PREFIX[part]):]}": v for k, v in state.items() if k.startswith(PREFIX[part])},
                   folder / f"tiny_{part}.pytmodel")
    return folder


def test_conversion_round_trip(tiny_state, tmp_path) -> None:
    folder = _save_official(tiny_state, tmp_path / "ckpt")
    model = create_model("glc-unips-tiny", checkpoint_path=folder)
    out = convert_official("glc-unips-tiny", folder, tmp_path / "glc-tiny.safetensors")
    again = create_model("glc-unips-tiny", checkpoint_path=out)
    assert not model.training
    for m in (model, again):
        assert all(torch.equal(v, tiny_state[k]) for k, v in m.state_dict().items())
    assert json.loads(out.with_suffix(".json").read_text())["extra"]["weights_licence"].startswith("GPL-3.0")
    images, mask = _inputs()
    with torch.no_grad():
        assert torch.equal(model(images, mask), again(images, mask))


def _one_line_error(path: Path, name: str = "glc-unips-tiny") -> str:
    return load_error(path, name)


def test_missing_partial_or_ambiguous_files_are_one_line(tiny_state, tmp_path) -> None:
    (tmp_path / "empty").mkdir()
    assert "no file matching '*_enc.pytmodel'" in _one_line_error(tmp_path / "empty")
    partial = _save_official(tiny_state, tmp_path / "partial", parts=("enc", "pred"))
    assert "no file matching '*_agg.pytmodel'" in _one_line_error(partial)
    assert "is not a folder of the published weights" in _one_line_error(partial / "tiny_enc.pytmodel")
    two = _save_official(tiny_state, tmp_path / "two")
    torch.save({}, two / "other_pred.pytmodel")
    assert "2 files (other_pred.pytmodel, tiny_pred.pytmodel)" in _one_line_error(two)


def test_mismatched_tensors_are_one_line_naming_them(tiny_state, tmp_path) -> None:
    removed = {k: v for k, v in tiny_state.items() if k != "aggregation.dec.0.S"}
    assert "missing tensors aggregation.dec.0.S;" in _one_line_error(_save_official(removed, tmp_path / "removed"))
    extra = dict(tiny_state, **{"prediction.regression.4.weight": torch.zeros(3, 3)})
    assert "unexpected tensors prediction.regression.4.weight" in _one_line_error(
        _save_official(extra, tmp_path / "extra"))
    # The full-size network's files do not fit the tiny one: the first misshaped tensor is named.
    wrong = dict(tiny_state, **{"encoder.attn.0.0.mab.fc_q.weight": torch.zeros(96, 96)})
    assert "encoder.attn.0.0.mab.fc_q.weight has shape 96x96 in the file" in _one_line_error(
        _save_official(wrong, tmp_path / "wrong"))


# -- the published preprocessing and the prediction CLI ------------------------------------------------------

def _object_folder(path: Path, centre: tuple[int, int] = (40, 38), axes: tuple[int, int] = (18, 27)) -> Path:
    """An 80 x 80 px object of 3 noisy 16-bit images (an elliptic mask) in our layout, which the published loader
    reads too (L*.png, mask.png)."""
    yy, xx = np.mgrid[:80, :80]
    mask = ((yy - centre[0]) / axes[0]) ** 2 + ((xx - centre[1]) / axes[1]) ** 2 < 1
    images = (np.random.default_rng(0).random((3, 80, 80, 3)) * 0.8).astype(np.float32)
    normals = np.zeros((80, 80, 3), np.float32)
    normals[..., 2] = 1
    return write_synthetic_object(path, images, mask, normals)


@pytest.mark.parametrize("centre", [(40, 38), (12, 38)], ids=["cropped", "touching-the-border"])
def test_preprocessing_equals_the_reference_loader(tmp_path, centre) -> None:
    """Mask and normalised images at 512 px against the published test loader, bit for bit (nearest-neighbour
    resizing of the 16-bit files); a mask near the border takes the whole image, as published."""
    from unips.data import load_object
    from unips.glc_preprocess import glc_crop, glc_inputs

    folder = _object_folder(tmp_path / "obj.data", centre=centre)
    loader = _reference("io.dataloader.realdata").dataloader(64, outdir=str(tmp_path / "ref"))
    np.random.seed(3)  # the published loader draws the order of the images
    loader.load([str(folder)], 0, prefix="L*", loader_imgsize=512)
    order = np.random.RandomState(3).permutation(3)
    obj = load_object(folder)
    crop = glc_crop(obj.mask)
    images, mask = glc_inputs(obj, crop)
    whole = (crop.r0, crop.r1, crop.c0, crop.c1) == (0, 80, 0, 80)
    assert whole == (centre[0] < 20) and crop.side == loader.h == 512
    assert np.array_equal(mask, loader.mask[..., 0])
    assert np.array_equal(images[order], loader.I.transpose(3, 0, 1, 2))


def test_predict_cli_runs_published_weights(tiny_state, tmp_path, capsys) -> None:
    from unips.predict import main

    folder = _object_folder(tmp_path / "obj.data")
    ckpt = _save_official(tiny_state, tmp_path / "ckpt")
    out = tmp_path / "pred"
    assert main(["--method", "model", "--model", "glc-unips-tiny", "--checkpoint", str(ckpt), "--input", str(folder),
                 "--out", str(out), "--res", "96"]) == 0
    info = json.loads((out / "obj" / "predict.json").read_text())
    assert info["model_name"] == "glc-unips-tiny" and info["tta"] == 1
    capsys.readouterr()
    # A folder of published weights without --model, and a checkpoint without its aggregation file: one line each.
    for flags, words in ((["--checkpoint", str(ckpt)], "--model"),
                         (["--model", "glc-unips-tiny", "--checkpoint",
                           str(_save_official(tiny_state, tmp_path / "part", parts=("enc", "pred")))],
                          "no file matching '*_agg.pytmodel'")):
        assert main(["--method", "model", *flags, "--input", str(folder), "--out", str(tmp_path / "p2")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("error: ") and words in err[0]


def test_non_finite_or_integer_weights_are_one_line_naming_the_file(tiny_state, tmp_path) -> None:
    """A NaN weight or a float weight stored as int64 in one published file is refused when loaded, naming that file
    and the tensor (issue 50: they loaded without a word); the network's own int64 buffers (the Swin windows'
    relative_position_index) stay int64, and float16 weights are floats."""
    nan = dict(tiny_state, **{"aggregation.dec.0.S": torch.full_like(tiny_state["aggregation.dec.0.S"], float("nan"))})
    text = _one_line_error(_save_official(nan, tmp_path / "nan"))
    assert text.startswith(f"{str(tmp_path / 'nan' / 'tiny_agg.pytmodel')!r}: tensor aggregation.dec.0.S holds ")
    assert "NaN" in text
    weight = "prediction.regression.0.weight"
    as_int = dict(tiny_state, **{weight: tiny_state[weight].round().to(torch.int64)})
    assert f"tiny_pred.pytmodel': tensor {weight} is int64, expected floating-point values" in _one_line_error(
        _save_official(as_int, tmp_path / "int"))
    index = next(k for k, v in tiny_state.items() if not v.is_floating_point())
    as_float = dict(tiny_state, **{index: tiny_state[index].float()})
    assert f"tensor {index} is float32, expected integer values" in _one_line_error(
        _save_official(as_float, tmp_path / "float_index"))
    half = {k: v.half() if v.is_floating_point() else v for k, v in tiny_state.items()}
    model = create_model("glc-unips-tiny", checkpoint_path=_save_official(half, tmp_path / "half"))
    assert model.state_dict()[index].dtype == torch.int64
