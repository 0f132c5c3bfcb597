"""The paper's steps 3-6 in its own stack (numpy + scipy), on the scene of
`cargo bench --bench perception -- geometry_10_masks`: a 640x480 depth
frame, a wall at 3.5 m and 10 box-shaped objects, one mask per object
(the object's pixels within its detection box, as the depth segmenter
gives them). Erosion (scipy.ndimage, 3x3), depth isolation, z-score
(scipy.stats, tau = 2), back-projection with the intrinsics and the
camera-to-base extrinsics, axis-aligned boxes. Prints the median of 200
views, in ms. The side-by-side figure in the README:

    .venv/bin/python -m pip install numpy scipy
    taskset -c 1 env OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
        .venv/bin/python benches/paper_geometry.py
"""

import statistics
import time

import numpy as np
from scipy import ndimage, stats

W, H = 640, 480
FX = FY = 385.0
CX, CY = 320.0, 240.0


def scene():
    d = np.full((H, W), 3.5, dtype=np.float32)
    masks = []
    for i in range(10):
        x0 = 20 + (i % 5) * 120
        y0 = 40 + (i // 5) * 220
        bw, bh = 90, 160
        z = 1.0 + 0.2 * i
        v, u = np.mgrid[y0 : y0 + bh, x0 : x0 + bw]
        d[y0 : y0 + bh, x0 : x0 + bw] = z + 0.002 * ((u * 7 + v * 13) % 11)
        m = np.zeros((H, W), dtype=bool)
        box = d[y0 - 10 : y0 + bh + 10, x0 - 10 : x0 + bw + 10]
        m[y0 - 10 : y0 + bh + 10, x0 - 10 : x0 + bw + 10] = box < 3.0
        masks.append(m)
    return d, masks


def steps_3_to_6(depth, masks, base_from_camera):
    kernel = np.ones((3, 3), dtype=bool)
    boxes = []
    for m in masks:
        eroded = ndimage.binary_erosion(m, structure=kernel)
        v, u = np.nonzero(eroded)
        z = depth[v, u]
        ok = (z > 0.1) & (z < 10.0)
        u, v, z = u[ok], v[ok], z[ok]
        keep = np.abs(stats.zscore(z)) < 2.0
        u, v, z = u[keep], v[keep], z[keep]
        x = (u - CX) * z / FX
        y = (v - CY) * z / FY
        pts = np.stack([x, y, z, np.ones_like(z)])
        pts = (base_from_camera @ pts)[:3].T
        boxes.append((pts.min(axis=0), pts.max(axis=0), len(pts)))
    return boxes


def main():
    depth, masks = scene()
    base_from_camera = np.eye(4)
    base_from_camera[:3, 3] = [0.3, 0.0, 0.9]
    boxes = steps_3_to_6(depth, masks, base_from_camera)
    points = sum(b[2] for b in boxes)
    times = []
    for _ in range(200):
        t = time.perf_counter()
        steps_3_to_6(depth, masks, base_from_camera)
        times.append((time.perf_counter() - t) * 1e3)
    print(f"paper_geometry_10_masks: {len(boxes)} boxes, {points} points, "
          f"median {statistics.median(times):.2f} ms")


if __name__ == "__main__":
    main()
