"""An optional asset folder: hdri/ (.hdr/.exr), meshes/ (.obj/.ply/.stl, any depth), textures/ (PBR sets)."""
from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from scenes.files import check_text_name
from scenes.meshes import MESH_SUFFIXES

_MAP_TAG = re.compile(
    r"^(?P<stem>.+?)[_\-](?P<tag>nor_dx|normal_?dx|col(?:_\d+)?|colou?r|diff(?:use)?|basecolor|albedo|rgh|rough(?:ness)?|"
    r"arm|met|metal(?:ness|lic)?|nor_gl|normal_?gl|nrm|normal)(?:[_\-].*)?$",
    re.IGNORECASE,
)
"""A texture map's name: <set>_<tag>[_<anything>], as Poly Haven (wood_diff_1k, wood_nor_gl_1k) and ambientCG
(Bricks076_1K-PNG_Color, _NormalGL) name them. A DirectX normal map (nor_dx, NormalDX: its green axis flipped) is
recognised to be left out, never read as an OpenGL one."""
_IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".exr", ".tif", ".tiff")


MAX_FILES = 200_000
"""An asset folder holding more files than this (a link to / or a home folder) is refused, not walked."""


def _files(folder: Path) -> list[Path]:
    """Every file below `folder`, following symbolic links (asset folders are often linked together), each real
    folder once (a link loop ends), at most `MAX_FILES` (FileNotFoundError-free ValueError naming --assets)."""
    out: list[Path] = []
    seen: set[str] = set()
    for root, dirs, names in os.walk(folder, followlinks=True):
        real = os.path.realpath(root)
        if real in seen:
            dirs[:] = []
            continue
        seen.add(real)
        out.extend(Path(root) / n for n in names)
        if len(out) > MAX_FILES:
            raise ValueError(f"--assets: {str(folder)!r} holds more than {MAX_FILES} files below it (at {root!r}: a "
                             "link to a large folder?); expected a folder of meshes, textures and maps")
    return sorted(out)


@dataclass
class TextureSet:
    """Files of one PBR material; roughness/metallic may come from channels of an ARM map."""

    name: str
    base_color: Path
    roughness: Path | None = None
    roughness_channel: int = 0
    metallic: Path | None = None
    metallic_channel: int = 0
    normal: Path | None = None


@dataclass
class AssetLibrary:
    """What an asset folder offers, in sorted order (so choices by index are reproducible)."""

    root: Path | None = None
    hdris: list[Path] = field(default_factory=list)
    meshes: list[Path] = field(default_factory=list)
    textures: list[TextureSet] = field(default_factory=list)

    @classmethod
    def scan(cls, root: str | Path | None) -> "AssetLibrary":
        """Index `root`; None gives an empty library. A missing or empty folder is a ValueError."""
        if root is None:
            return cls()
        root = Path(root)
        if not root.is_dir():
            raise FileNotFoundError(f"--assets: folder {str(root)!r} does not exist")
        lib = cls(root=root)
        if (root / "hdri").is_dir():
            lib.hdris = sorted(p for p in _files(root / "hdri") if p.suffix.lower() in (".hdr", ".exr"))
        if (root / "meshes").is_dir():
            lib.meshes = sorted(p for p in _files(root / "meshes") if p.suffix.lower() in MESH_SUFFIXES)
        if (root / "textures").is_dir():
            lib.textures = _texture_sets(root / "textures")
        named = [*lib.hdris, *lib.meshes, *(f for t in lib.textures for f in (t.base_color, t.roughness, t.metallic,
                                                                             t.normal) if f is not None)]
        for path in named:  # the renderer, the mesh reader and scene.json take a name as text only
            check_text_name(path, "--assets")
        if not (lib.hdris or lib.meshes or lib.textures):
            raise ValueError(
                f"--assets: folder {str(root)!r} has no hdri/*.hdr|exr, meshes/*.obj|ply|stl or textures/ sets"
            )
        return lib


    def check_drawn(self, folder: str | None, shapes: str, lights: list[str]) -> None:
        """ValueError naming --shapes or --assets where the run asks for meshes the folder lacks, or where nothing of
        it can be drawn: textures serve every material, meshes every shape but `procedural`, maps the light families
        lit by an environment."""
        from wildgen.light_families import ENVIRONMENT_FAMILIES

        if shapes == "mesh" and not self.meshes:
            raise ValueError(f"--shapes: 'mesh' needs an --assets folder with meshes/, {folder!r} has none")
        if folder and not (self.textures or (self.meshes and shapes != "procedural")
                           or (self.hdris and set(lights) & set(ENVIRONMENT_FAMILIES))):
            raise ValueError(f"--assets: nothing in {folder!r} can be drawn with --shapes {shapes} and --lights "
                             f"{','.join(lights)} (its meshes need mesh or any shapes, its maps a family lit by the "
                             f"environment: {', '.join(ENVIRONMENT_FAMILIES)}), so it would do nothing; leave it out")

    def check(self) -> None:
        """Decode every file once, up front (the driver does it before any render): a file that cannot be read
        would fail every object that draws it, so the run is refused with a ValueError naming it."""
        from scenes.envmaps import load_environment
        from scenes.meshes import load_mesh
        from scenes.textures import outside_unit_range, read_image_file

        jobs = [(p, load_mesh) for p in self.meshes] + [(p, load_environment) for p in self.hdris]
        for ts in self.textures:
            jobs += [
                (p, read_image_file) for p in (ts.base_color, ts.roughness, ts.metallic, ts.normal) if p is not None
            ]
        need: dict = {}  # the channels each map must hold: an ARM map's G and B where read, a normal map's 3
        for ts in self.textures:
            for p, c in ((ts.roughness, ts.roughness_channel + 1), (ts.metallic, ts.metallic_channel + 1),
                         (ts.normal, 3)):
                need[p] = max(c, need.get(p, 1))
        bad = []
        for path, read in dict(jobs).items():
            try:
                data = read(Path(path))
            except (ValueError, OSError) as exc:
                bad.append(f"{exc}")
                continue
            if read is not read_image_file:
                continue
            if why := outside_unit_range(data, path):  # the renderer's rule, named here by the asset's own file
                bad.append(why)
            elif need.get(path, 1) > (have := data.shape[2] if data.ndim == 3 else 1):
                bad.append(f"{str(path)!r} has {have} channel(s), {need[path]} are read (ARM: occlusion, roughness, "
                           "metallic; a normal map: x, y, z)")
        if bad:
            more = f" (and {len(bad) - 1} more unreadable file(s))" if len(bad) > 1 else ""
            raise ValueError(f"--assets: {bad[0]}{more}; fix or remove the file")


def _texture_sets(folder: Path) -> list[TextureSet]:
    groups: dict[tuple[Path, str], dict[str, Path]] = {}
    for p in _files(folder):
        if p.suffix.lower() not in _IMAGE_SUFFIXES:
            continue
        m = _MAP_TAG.match(p.stem)
        if not m:
            continue
        tag = m.group("tag").lower()
        kind = (
            "base" if tag.startswith(("col", "diff", "basecolor", "albedo"))
            else "rough" if tag.startswith(("rgh", "rough"))
            else "arm" if tag == "arm"
            else "metal" if tag.startswith("met")
            else "dx" if "dx" in tag  # the set keeps no normal map rather than a wrong one
            else "normal"
        )
        groups.setdefault((p.parent, m.group("stem").lower()), {}).setdefault(kind, p)
    sets = []
    for (parent, stem), maps in sorted(groups.items(), key=lambda kv: (str(kv[0][0]), kv[0][1])):
        if "base" not in maps:
            continue
        ts = TextureSet(name=f"{parent.name}/{stem}", base_color=maps["base"], normal=maps.get("normal"))
        if "rough" in maps:
            ts.roughness = maps["rough"]
        elif "arm" in maps:
            ts.roughness, ts.roughness_channel = maps["arm"], 1  # ARM: R occlusion, G roughness, B metal
        if "metal" in maps:
            ts.metallic = maps["metal"]
        elif "arm" in maps:
            ts.metallic, ts.metallic_channel = maps["arm"], 2
        sets.append(ts)
    return sets
