#!/usr/bin/env bash
# Shared fixtures of a bad-input sweep (scripts/sweep/run_sweep.py), about 3 minutes on 2 cores:
#   data/  data8/   3 objects x 4 and 8 images, 32 px (wildgen.make)
#   pred/  pred8/   predictions of them by the shipped model (unips.predict --method model)
#   run/            a 2-step glc-test training run (unips.train)
#   shards/         data8 as WebDataset shards (wildgen.export)
#   photos/         8 JPEG photos made from data8/00000.data; mask.png, a binary mask of them
#   ballPNG/        DiLiGenT ball (only when ../shared holds it)
#   assets/         a small asset library (3 meshes, 2 HDR maps) when ../shared holds one
#   afile, empty/   a plain file and an empty folder
# Usage: bash scripts/sweep/fixtures.sh /tmp/sweep/fx   (the repo's .venv is used)
set -euo pipefail
F=${1:?usage: fixtures.sh FOLDER}
REPO=$(cd "$(dirname "$0")/../.." && pwd)
PY=${PY:-$REPO/.venv/bin/python}
SHARED=${SHARED:-$REPO/../shared}
mkdir -p "$F"
F=$(cd "$F" && pwd)
cd "$REPO"
[ -d "$F/data" ] || $PY -m wildgen.make --objects 3 --images 4 --res 32 --spp 8 --seed 1 --out "$F/data"
[ -d "$F/data8" ] || $PY -m wildgen.make --objects 3 --images 8 --res 32 --spp 8 --seed 8 --out "$F/data8"
[ -d "$F/pred" ] || $PY -m unips.predict --method model --input "$F/data" --out "$F/pred"
[ -d "$F/pred8" ] || $PY -m unips.predict --method model --input "$F/data8" --out "$F/pred8"
[ -d "$F/run" ] || $PY -m unips.train --data "$F/data8" --out "$F/run" --model glc-test --steps 2
[ -d "$F/shards" ] || $PY -m wildgen.export --format webdataset --data "$F/data8" --out "$F/shards"
if [ ! -d "$F/photos" ]; then
  $PY - "$F" <<'EOF'
import sys
from pathlib import Path

import cv2
import numpy as np

F = Path(sys.argv[1])
src = F / "data8" / "00000.data"
(F / "photos").mkdir()
imgs = sorted(p for p in src.iterdir() if p.suffix in (".png", ".exr") and p.stem.startswith("L"))
if not imgs:
    imgs = sorted(p for p in src.iterdir() if p.name.lower().startswith(("l0", "l1", "img")))
for i, p in enumerate(imgs[:8]):
    im = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
    im = im.astype(np.float32)
    im = im / max(float(im.max()), 1e-6)
    im8 = (np.clip(im, 0, 1) ** (1 / 2.2) * 255).astype(np.uint8)
    im8 = cv2.resize(im8, (64, 64), interpolation=cv2.INTER_NEAREST)
    cv2.imwrite(str(F / "photos" / f"photo{i:02d}.jpg"), im8, [cv2.IMWRITE_JPEG_QUALITY, 95])
mask = cv2.imread(str(src / "mask.png"), cv2.IMREAD_GRAYSCALE)
mask = cv2.resize(mask, (64, 64), interpolation=cv2.INTER_NEAREST)
cv2.imwrite(str(F / "mask.png"), np.where(mask > 127, 255, 0).astype(np.uint8))
EOF
fi
if [ -d "$SHARED/data/diligent" ] && [ ! -e "$F/ballPNG" ]; then
  ball=$(find "$SHARED/data/diligent" -maxdepth 3 -type d -name 'ballPNG' | head -1)
  [ -n "$ball" ] && cp -r "$ball" "$F/ballPNG"
fi
if [ -d "$SHARED/assets" ] && [ ! -d "$F/assets" ]; then
  mkdir -p "$F/assets/meshes" "$F/assets/hdri"
  for m in sphere torus goathead; do  # the smallest meshes, a folder each as in ../shared
    [ -d "$SHARED/assets/meshes/$m" ] && cp -r "$SHARED/assets/meshes/$m" "$F/assets/meshes/"
  done
  find "$SHARED/assets/hdri" -name '*.hdr' | sort | head -2 | xargs -r -I{} cp {} "$F/assets/hdri/"
fi
echo "a plain file" > "$F/afile"
mkdir -p "$F/empty"
ls "$F/photos" | wc -l
touch "$F/DONE"
echo "fixtures in $F"
