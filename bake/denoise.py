"""Light-map denoising with Intel Open Image Denoise (its RTLightmap filter, made for HDR light maps)."""
from __future__ import annotations

import numpy as np
import pyoidn


def denoise_lightmap(irradiance: np.ndarray) -> np.ndarray:
    """(H, W, 3) HDR irradiance -> denoised copy. Call on a dilated page so chart
    borders have no empty (black) neighbours to bleed in."""
    out = pyoidn.denoise(np.ascontiguousarray(irradiance, dtype=np.float32),
                         filter_type=pyoidn.OIDN_FILTER_TYPE_RT_LIGHTMAP, quality="high")
    # OIDN never returns negatives for HDR input in practice; keep the guarantee explicit.
    return np.nan_to_num(np.maximum(out, 0.0), nan=0.0, posinf=0.0).astype(np.float32)
