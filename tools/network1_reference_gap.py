#!/usr/bin/env python3
"""Dev-time check of Network-1's default reference (docs/evaluation.md): per set of an hdrsynth
test set with EV -3/0 static frames and their noise-free copies, how far the Mertens weights of
the noisy pair are from those of the clean pair. Independent of hdrsynth's code (OpenCV).
usage: python tools/network1_reference_gap.py TESTSET   (needs opencv-python-headless, numpy)
"""
import cv2, numpy as np, sys, os, glob
root=sys.argv[1]
def W(img):
    x=img.astype(np.float32)/255.0
    g=cv2.cvtColor(x, cv2.COLOR_BGR2GRAY)
    c=np.abs(cv2.Laplacian(g, cv2.CV_32F))
    s=x.std(axis=2)
    return c*s+1e-12
for d in sorted(glob.glob(root+'/*_iso*')):
    f=lambda n: cv2.imread(os.path.join(d,'static',n))
    lo,hi,clo,chi=f('ev-3.png'),f('ev+0.png'),f('clean_ev-3.png'),f('clean_ev+0.png')
    Wl,Wh,Cl,Ch=W(lo),W(hi),W(clo),W(chi)
    wn=Wh/(Wl+Wh); wc=Ch/(Cl+Ch)
    flat=(Cl<1e-11)&(Ch<1e-11)
    nflat=(Wl<1e-11)&(Wh<1e-11)
    print(f"{os.path.basename(d):20s} clean-flat {flat.mean():.3f} noisy-flat {nflat.mean():.3f} "
          f"mean|wn-wc| all {np.abs(wn-wc).mean():.3f} flat {np.abs(wn-wc)[flat].mean() if flat.any() else float('nan'):.3f} "
          f"nonflat {np.abs(wn-wc)[~flat].mean():.3f}  mean wn {wn.mean():.3f} wc {wc.mean():.3f}")
