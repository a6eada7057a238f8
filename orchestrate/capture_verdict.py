"""The capture's verdict: the level and headline a photographer reads first (`level`, from the stated expected error,
the physical check and the capture warnings) and the check's answer in words (`verdict`); report.json `verdict`."""
from __future__ import annotations

import numpy as np

USABLE_DEG = 15.0
"""A map is "usable" when its stated mean error is at most this (and the check judged it, nothing below demotes it):
about the error of a good calibrated photometric-stereo method on DiLiGenT's harder objects; beyond it, shape and
shading derived from the map are visibly off."""
PIXEL_USABLE_DEG = 25.0
"""The headline's "over N % of the object": the share of its pixels whose stated error is at most this."""
DEMOTING_WARNINGS = {
    "doubtful_mask": "the automatic mask may be wrong",
    "camera_moved": "the camera moved between photos",
}
"""Capture warnings that keep a map from "usable" whatever its stated error (the error model never saw them)."""
LEVELS = ("usable", "use with care", "not checked")
"""The verdict's levels, best first (report.json `verdict.level`)."""


def level(check: dict, stated, why_unstated: str | None, warnings: list) -> tuple[str, str]:
    """(verdict level, the headline a photographer reads first) of a capture: "not checked" where the images cannot
    judge it or no error is stated, else "usable" when the stated mean is at most USABLE_DEG and no warning of
    DEMOTING_WARNINGS was raised, else "use with care"."""
    if stated is None:
        return "not checked", f"not checked: no expected error is stated ({why_unstated})"
    share = float(np.mean(stated.per_pixel[np.isfinite(stated.per_pixel)] <= PIXEL_USABLE_DEG))
    lo, hi = stated.interval_80
    figure = (f"expected error about {stated.mean:.0f} deg (80 %: {lo:.0f}-{hi:.0f} deg), within {PIXEL_USABLE_DEG:.0f}"
              f" deg over {share:.0%} of the object")
    if not check["trusted"]:  # on a doubted automatic mask, the mask is named first (as in mask_first)
        on = " on an automatic mask that may not be the object (doubtful_mask: give --mask FILE)" \
            if mask_doubted(warnings) else ""
        return "not checked", f"not checked{on}: {check.get('why')}; the model's {figure}"
    demoted = [DEMOTING_WARNINGS[w.code] for w in warnings if w.code in DEMOTING_WARNINGS]
    if stated.mean > USABLE_DEG:
        demoted.insert(0, f"above the {USABLE_DEG:.0f} deg of a usable map")
    if demoted:
        return "use with care", f"use with care: {figure}; {'; '.join(demoted)}"
    return "usable", f"usable: {figure}"


def verdict(check: dict, refined: dict | None) -> dict:
    """What the user has in hand, in words: can the images judge this capture, how well does the final map explain
    them, was it refined."""
    noise = check.get("noise_rel_l1")
    judged = refined["judged_after_rel_l1"] if refined and refined.get("accepted") else check.get("judged_rel_l1")
    out = {"images_can_judge": bool(check["trusted"]), "why": check.get("why"),
           "explained_fraction": check.get("explained_fraction"), "judged_rel_l1": judged, "noise_rel_l1": noise,
           "residual_in_noise_units": (judged / noise) if judged is not None and noise else None,
           "refined": bool(refined and refined.get("accepted")), "resolution": check.get("resolution"),
           "refinement": refined.get("why") if refined else "not run: the images cannot judge this capture"
           if not check["trusted"] else "not run (--no-refine)"}
    if not check["trusted"]:
        out["summary"] = ("The images cannot judge this capture, so the normal map is the model's, unchecked: "
                          f"{check.get('why')}")
    else:
        units = out["residual_in_noise_units"]
        out["summary"] = (
            f"The images can judge this capture ({check['explained_fraction']:.0%} of the object is "
            f"explained by the fitted light); the final map leaves a residual of "
            f"{units:.1f} times the image noise"
            if units is not None
            else "The images can judge this capture"
        )
        out["summary"] += ("; the model's map is kept." if not out["refined"] else
                           "; it was refined, and the images tell the refined map apart from the model's." if
                           refined.get("told_apart") else
                           "; it was refined, but the change is within what the images resolve: the refined map fits "
                           "the physics better, which does not show it is closer to the surface.")
    return out


def mask_doubted(warnings: list) -> bool:
    """Whether the capture's warnings doubt its automatic mask (`doubtful_mask`): then the mask is named first."""
    return any(w.code == "doubtful_mask" for w in warnings)


def mask_first(exc: Exception, warnings: list) -> Exception:
    """A refusal on an automatic mask that the light variation doubts (`doubtful_mask`) names the mask first: a
    chrome ball, a lamp or the table taken for the object makes the images look black, constant or clipped, and
    then the exposure or the light the refusal names is not what to change. Any other refusal (one not naming
    --input) is returned as is."""
    said = str(exc)
    if not (said.startswith("--input: ") and mask_doubted(warnings)):
        return exc
    said = said.removeprefix("--input: ")
    return ValueError(f"--mask: the automatic mask may not be the object (the doubtful_mask warning above), and on it "
                      f"the check says: {said}; draw the object's mask and give it (--mask FILE: white object on "
                      "black, the size of the photos)")
