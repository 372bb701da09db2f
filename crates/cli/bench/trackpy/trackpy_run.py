"""trackpy 0.7 (numba engine) on a folder of frames, one thread: locate (diameter 9, the
frames' discs), link (search range 5, memory 3); prints the seconds and the track count.
Usage: trackpy_run.py FRAMES_DIR."""
import glob
import os
import sys
import time

import numpy as np
import trackpy as tp
from PIL import Image

files = sorted(glob.glob(os.path.join(sys.argv[1], "*.png")))
tp.quiet()
start = time.perf_counter()
frames = [np.asarray(Image.open(f), dtype=np.float64) for f in files]
features = tp.batch(frames, 9, minmass=1000, engine="numba", processes=1)
tracks = tp.link(features, 5, memory=3)
elapsed = time.perf_counter() - start
print(f"{elapsed:.3f} {tracks['particle'].nunique()}")
