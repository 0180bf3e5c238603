#!/usr/bin/env python3
"""OpenCV StereoSGBM as the peer of `parallax eval stereo --peer opencv`.

Usage: opencv_sgbm.py [--repeat N] OUT_DIR SCENE_DIR...

For every Middlebury scene folder (im0.png, im1.png, calib.txt) and both modes (MODE_SGBM_3WAY,
MODE_HH4) it writes OUT_DIR/<scene>.<mode>.pfm (disparity, inf = no estimate, Middlebury PFM) and
prints one JSON line {"scene", "mode", "ms", "pfm"} where ms times compute() alone (the median of
N calls on the same StereoSGBM object, N = --repeat, default 1, as `parallax eval stereo --repeat`
times its own matcher), after a first line {"opencv": VERSION} (the peer's timings and scores
differ between releases).
Parameters as in shared/data/README.md: blockSize 3, P1 = 8*3*9, P2 = 32*3*9, uniquenessRatio 10,
speckleWindowSize 100, speckleRange 32, disp12MaxDiff 1; numDisparities = ndisp rounded up to 16.
"""
import json
import os
import sys
import time

import cv2
import numpy as np


def ndisp_of(calib_path):
    with open(calib_path) as f:
        for line in f:
            key, _, value = line.partition("=")
            if key.strip() == "ndisp":
                return int(float(value))
    raise SystemExit(f"{calib_path}: no ndisp")


def write_pfm(path, disparity):
    data = np.where(np.isfinite(disparity), disparity, np.inf).astype("<f4")
    h, w = data.shape
    with open(path, "wb") as f:
        f.write(f"Pf\n{w} {h}\n-1\n".encode())
        f.write(np.flipud(data).tobytes())


def main():
    args = sys.argv[1:]
    repeat = 1
    if args[:1] == ["--repeat"]:
        repeat = max(1, int(args[1]))
        args = args[2:]
    out_dir, scenes = args[0], args[1:]
    os.makedirs(out_dir, exist_ok=True)
    print(json.dumps({"opencv": cv2.__version__}), flush=True)
    modes = {"SGBM_3WAY": cv2.STEREO_SGBM_MODE_SGBM_3WAY, "HH4": cv2.STEREO_SGBM_MODE_HH4}
    for scene in scenes:
        name = os.path.basename(os.path.normpath(scene))
        left = cv2.imread(os.path.join(scene, "im0.png"), cv2.IMREAD_COLOR)
        right = cv2.imread(os.path.join(scene, "im1.png"), cv2.IMREAD_COLOR)
        if left is None or right is None:
            raise SystemExit(f"{scene}: cannot read im0.png/im1.png")
        ndisp = ndisp_of(os.path.join(scene, "calib.txt"))
        num = (ndisp + 15) // 16 * 16
        for mode_name, mode in modes.items():
            sgbm = cv2.StereoSGBM_create(
                minDisparity=0, numDisparities=num, blockSize=3,
                P1=8 * 3 * 9, P2=32 * 3 * 9, disp12MaxDiff=1, uniquenessRatio=10,
                speckleWindowSize=100, speckleRange=32, mode=mode)
            times = []
            for _ in range(repeat):
                start = time.perf_counter()
                raw = sgbm.compute(left, right)
                times.append((time.perf_counter() - start) * 1e3)
            ms = sorted(times)[len(times) // 2]
            disparity = raw.astype(np.float32) / 16.0
            disparity[raw < 0] = np.inf
            pfm = os.path.join(out_dir, f"{name}.{mode_name}.pfm")
            write_pfm(pfm, disparity)
            print(json.dumps({"scene": name, "mode": mode_name, "ms": ms, "pfm": pfm}), flush=True)


if __name__ == "__main__":
    main()
