"""What the side-by-side scripts share (`depth_vs_sgbm.py`, `depth_heldout.py`): reading
`hvs depth`'s PFM files and scoring disparities as issue 25 scores them."""
import numpy as np


def read_pfm(path):
    """A PFM file as rows top to bottom (`h x w x channels`)."""
    with open(path, "rb") as f:
        kind = f.readline().strip()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4")
    return data.reshape(h, w, 3 if kind == b"PF" else 1)[::-1]


def rates(disp, returned, gt):
    """Returned %, > 2 px % and > 1 px % of the returned, as issue 25 counts them: every pixel
    with a truth `gt` whose match lies inside the right image."""
    xs = np.arange(gt.shape[1])[None, :]
    valid = np.isfinite(gt) & (xs - gt >= 0)
    ret = valid & returned
    err = np.abs(disp - gt)
    n = max(int(ret.sum()), 1)
    return (100 * ret.sum() / valid.sum(), 100 * (ret & (err > 2)).sum() / n,
            100 * (ret & (err > 1)).sum() / n)
