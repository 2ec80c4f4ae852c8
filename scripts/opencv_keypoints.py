#!/usr/bin/env python3
"""Export OpenCV's Harris and Shi-Tomasi keypoints (and its Gaussian blur) for maps, to compare with ours.

Usage: opencv_keypoints.py OUT_DIR IMAGE.pgm [IMAGE.pgm ...]

For each IMAGE (8-bit grey), writes OUT_DIR/<stem>.harris.csv, <stem>.shi_tomasi.csv (x,y per line) and
<stem>.blur.pgm, with the paper's configuration as ogm-corners uses it:
- blur: GaussianBlur(3x3, sigma 1), OpenCV's bit-exact 8-bit path;
- Harris: cornerHarris(blockSize=3, ksize=3, k=0.04) on the blurred image; keypoints are responses above
  0.01 x the maximum (and above 0) that are 3x3 local maxima (response == dilate(response));
- Shi-Tomasi: goodFeaturesToTrack(maxCorners=0, qualityLevel=0.01, minDistance=3, blockSize=3,
  gradient size 3) on the blurred image.
"""
import os
import sys

import cv2
import numpy as np


def main() -> int:
    if len(sys.argv) < 3:
        print(__doc__, file=sys.stderr)
        return 2
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    for path in sys.argv[2:]:
        img = cv2.imread(path, cv2.IMREAD_UNCHANGED)
        if img is None or img.dtype != np.uint8 or img.ndim != 2:
            print(f"{path}: not an 8-bit grey image", file=sys.stderr)
            return 2
        stem = os.path.join(out, os.path.splitext(os.path.basename(path))[0])
        blur = cv2.GaussianBlur(img, (3, 3), 1.0, borderType=cv2.BORDER_REFLECT_101)
        cv2.imwrite(stem + ".blur.pgm", blur)
        r = cv2.cornerHarris(blur, blockSize=3, ksize=3, k=0.04)
        keep = (r > 0.01 * r.max()) & (r > 0) & (r == cv2.dilate(r, np.ones((3, 3), np.uint8)))
        ys, xs = np.nonzero(keep)
        with open(stem + ".harris.csv", "w") as f:
            f.write("x,y\n")
            for x, y in zip(xs, ys):
                f.write(f"{x},{y}\n")
        # gradientSize defaults to 3 (the keyword is not exposed in every binding).
        pts = cv2.goodFeaturesToTrack(blur, maxCorners=0, qualityLevel=0.01, minDistance=3, blockSize=3,
                                      useHarrisDetector=False)
        with open(stem + ".shi_tomasi.csv", "w") as f:
            f.write("x,y\n")
            for p in ([] if pts is None else pts.reshape(-1, 2)):
                f.write(f"{int(round(p[0]))},{int(round(p[1]))}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
