"""What a registered model expects of its inputs (its data contract), carried by its registry entry, as timm's
pretrained_cfg carries a model's input size and normalisation.

Every model's inputs are K RGB images (float32, linear) of one object and its mask. How they are cropped, resized,
normalised and how many the network sees is its `InputContract`: `unips.inference` and `unips.predict` read it from
the entry (`unips.models.input_contract`), and the published loaders (`unips.glc_preprocess`,
`unips.sdm_preprocess`) take their constants from the published contracts below. The models of this toolkit share
`UNIPS_INPUTS` (ours); each shipped-weights entry (`registry.Pretrained`) adds the resolution it was trained at.
"""

from __future__ import annotations

from dataclasses import dataclass

VIEWS = (1, 2, 4, 8)
"""Allowed numbers of test-time views (`unips.inference.TTA_VIEWS`, the first N of `unips.augment.DIHEDRAL`)."""

PREPROCESSING = {
    "unips": "ours (`unips.preprocess`): square crop around the mask, each image divided by its masked mean",
    "glc-unips": "the published UniPS loader (`unips.glc_preprocess`): crop resized to the working side by nearest "
                 "neighbour, each image divided by its masked mean",
    "sdm-unips": "the published SDM-UniPS loader (`unips.sdm_preprocess`): crop resized (bicubic) to a multiple "
                 "of 512, each image divided by the maximum of its masked channel mean",
}
"""The preprocessings a contract may name, and what each does (for messages and docs)."""


@dataclass(frozen=True)
class InputContract:
    """The data contract of a registered model: its preprocessing and the limits its inputs get."""

    preprocess: str = "unips"
    """Which preprocessing its inputs get in `unips.inference.run_model` (a key of `PREPROCESSING`)."""
    margin: int = 4
    """Pixels around the mask's bounding box kept in the crop."""
    side: int | None = None
    """Working side the crop is resized to by default (`--res` replaces it); None: the crop's own side (ours) or
    the published loader's rule (SDM-UniPS: a multiple of 512 from the crop's longest side)."""
    max_images: int | None = None
    """Most images the network sees (a seeded random subset when there are more); None: all of them."""
    views: int = 2
    """Test-time views averaged by default (`--tta`; `unips.inference.TTA_VIEWS`): 1 for the published networks
    (as their code runs), 2 for ours (`unips.inference.DEFAULT_TTA`)."""
    patch: int | None = None
    """Side of the sub-images of `--scalable` (SDM-UniPS); None: the model has no `--scalable`."""
    train_resolution: int | None = None
    """Side (px) of the rendered images its weights were trained on (`unips.train --res`); None: not trained here."""

    def __post_init__(self) -> None:
        def bad(name: str, expected: str) -> ValueError:
            return ValueError(f"InputContract.{name}={getattr(self, name)!r}: expected {expected}")

        if self.preprocess not in PREPROCESSING:
            raise bad("preprocess", f"one of {', '.join(PREPROCESSING)}")
        if self.margin < 0:
            raise bad("margin", "a non-negative number of pixels")
        for name in ("side", "max_images", "patch", "train_resolution"):
            if getattr(self, name) is not None and getattr(self, name) < 1:
                raise bad(name, "None or a positive integer")
        if self.views not in VIEWS:
            raise bad("views", f"one of {', '.join(map(str, VIEWS))}")

    @property
    def published(self) -> bool:
        """Whether the inputs get a published network's own preprocessing (not ours)."""
        return self.preprocess != "unips"


UNIPS_INPUTS = InputContract()
"""Ours (`unips.preprocess`): the crop's own side, every image, two views."""

GLC_UNIPS_INPUTS = InputContract(preprocess="glc-unips", margin=4, side=512, max_images=64, views=1)
"""The published UniPS test run: 4 px margin (fixed in its loader), working side 512 (its loader and decoder side),
at most 64 images (its test_maxNumberOfImages), one view."""

SDM_UNIPS_INPUTS = InputContract(preprocess="sdm-unips", margin=8, max_images=10, views=1, patch=512)
"""The published SDM-UniPS run: 8 px margin (its --mask_margin), at most 10 images (its --max_image_num), one view,
`--scalable` sub-images of 512 px (fixed in its code)."""
