#!/usr/bin/env python3
"""Calibrates with OpenCV's cv2.calibrateCamera from the views in a JSON file, for comparing
evcal's solver with OpenCV's on identical input (tests/tests/end_to_end/opencv.rs, scripts/bench-calib.sh).

    python3 scripts/opencv-calibrate.py INPUT.json > OUTPUT.json

INPUT: {"image_size": [w, h], "flags": ["FIX_K3", ...], "guess": [fx, fy, cx, cy] or null,
        "max_iterations": n, "epsilon": e, "views": [{"object": [[x, y, z], ...],
        "image": [[u, v], ...]}, ...]}
OUTPUT: {"fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "rms_px", "seconds",
         "opencv": version}
"""
import json
import sys
import time

import cv2
import numpy as np


def main() -> None:
    spec = json.load(open(sys.argv[1]))
    objects = [np.asarray(v["object"], dtype=np.float32) for v in spec["views"]]
    images = [np.asarray(v["image"], dtype=np.float32).reshape(-1, 1, 2) for v in spec["views"]]
    # OpenCV takes its points in single precision: evcal is given the same rounded values.
    flags = 0
    for name in spec.get("flags", []):
        flags |= getattr(cv2, "CALIB_" + name)
    k = np.eye(3)
    guess = spec.get("guess")
    if guess is not None:
        k = np.array([[guess[0], 0, guess[2]], [0, guess[1], guess[3]], [0, 0, 1]], dtype=np.float64)
        flags |= cv2.CALIB_USE_INTRINSIC_GUESS
    criteria = (
        cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS,
        int(spec.get("max_iterations", 30)),
        float(spec.get("epsilon", sys.float_info.epsilon)),
    )
    size = tuple(spec["image_size"])
    started = time.perf_counter()
    rms, k, dist, _, _ = cv2.calibrateCamera(objects, images, size, k, np.zeros(5), flags=flags, criteria=criteria)
    seconds = time.perf_counter() - started
    d = dist.ravel().tolist() + [0.0] * 5
    json.dump(
        {
            "fx": k[0, 0], "fy": k[1, 1], "cx": k[0, 2], "cy": k[1, 2],
            "k1": d[0], "k2": d[1], "p1": d[2], "p2": d[3], "k3": d[4],
            "rms_px": rms, "seconds": seconds, "opencv": cv2.__version__,
        },
        sys.stdout,
    )


if __name__ == "__main__":
    main()
