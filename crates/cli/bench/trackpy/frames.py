"""Frames for the side-by-side run: N discs of radius 4 px (amplitude 200 over 30, each pixel
its covered fraction) random-walking freely at 0.5-3 px a frame, no two closer than 9 px,
noise 5, 512 x 512 8-bit grey PNG. Usage: frames.py N FRAMES OUT_DIR (writes OUT_DIR/frames/
and OUT_DIR/truth.csv). Seeded: the same N gives the same frames."""
import os
import sys

import numpy as np
from PIL import Image

n, count, out = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
size, radius, apart = 512, 4.0, 9.0
rng = np.random.default_rng(100 + n)
os.makedirs(os.path.join(out, "frames"), exist_ok=True)
pos = []
while len(pos) < n:
    p = rng.uniform(radius + 1, size - radius - 2, 2)
    if all(np.hypot(*(p - q)) >= apart + 2 for q in pos):
        pos.append(p)
pos = np.array(pos)
speed = rng.uniform(0.5, 3.0, n)
yy, xx = np.mgrid[0:size, 0:size]
rows = ["frame,particle,x,y"]
for k in range(count):
    img = np.full((size, size), 30.0)
    for i, (x, y) in enumerate(pos):
        x0, x1 = max(0, int(x - radius - 2)), int(x + radius + 3)
        y0, y1 = max(0, int(y - radius - 2)), int(y + radius + 3)
        d = np.hypot(xx[y0:y1, x0:x1] - x, yy[y0:y1, x0:x1] - y)
        img[y0:y1, x0:x1] += 200 * np.clip(radius + 0.5 - d, 0, 1)
        rows.append(f"{k},p{i},{x:.4f},{y:.4f}")
    img += rng.normal(0, 5, img.shape)
    Image.fromarray(np.clip(np.rint(img), 0, 255).astype(np.uint8)).save(
        os.path.join(out, "frames", f"frame_{k:05d}.png"))
    for i in rng.permutation(n):
        for _ in range(10):
            a = rng.uniform(0, 2 * np.pi)
            q = pos[i] + speed[i] * np.array([np.cos(a), np.sin(a)])
            if not (radius + 1 <= q[0] <= size - radius - 2 and radius + 1 <= q[1] <= size - radius - 2):
                continue
            d = np.hypot(*(pos - q).T)
            d[i] = 1e9
            if d.min() >= apart:
                pos[i] = q
                break
with open(os.path.join(out, "truth.csv"), "w") as f:
    f.write("\n".join(rows) + "\n")
