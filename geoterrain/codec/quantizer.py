"""The quantizer's description: how heights map to int64 codes (:class:`Quantizer`).

Apart from :mod:`geoterrain.codec.quantize`'s kernels, so that reading a store's
metadata (:mod:`geoterrain.store.check`) loads no compiler.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

__all__ = ["DECIMAL_STEPS", "FINE_STEPS", "MAX_BINS", "Quantizer", "describe_codec"]

_I64_MAX = np.int64(np.iinfo(np.int64).max)
# lossless steps finer than 1 tried on float sources, coarsest first, and whether each
# is a decimal ("decimal" mode) or binary ("int" mode, exact in floats): the first under
# which every height decodes to itself is taken (fine_quantizer)
FINE_STEPS = tuple(sorted([(2.0 ** -m, False) for m in range(1, 9)]
                          + [(10.0 ** -d, True) for d in range(1, 5)], reverse=True))
DECIMAL_STEPS = tuple(s for s, d in FINE_STEPS if d)
MAX_BINS = (1 << 20) - 1


_I32_MAX = np.int64(np.iinfo(np.int32).max)


@dataclass(frozen=True)
class Quantizer:
    """How heights map to int64 codes.

    Attributes
    ----------
    mode : {"int", "decimal", "quantized", "float"}
        ``"int"``: lossless, heights are exactly ``offset + q * step`` (integer DEMs,
        Terrain-RGB's 0.1 m). ``"decimal"``: lossless, heights are exactly the decimal
        ``q / 10^d`` (``step`` = 10^-d, offset 0) rounded to ``float_bits`` (32 for a
        source of at most 4 bytes): a float DEM written with d decimal places, as many LiDAR and
        survey products are (1238.6 ft is the float32 nearest 12386 / 10, not
        ``12386 * 0.1``). ``"quantized"``: ``q = round((z - offset) / step)`` with
        ``step`` slightly below ``2 * codec_error`` so ``|decoded - z| <= codec_error``.
        ``"float"``: lossless bit-exact floats; codes are the float bit patterns mapped to
        order-preserving integers (``float_bits`` = 32 or 64).
    step, offset : float
        Code spacing and origin (unused in ``"float"`` mode).
    codec_error : float
        Guaranteed bound on ``|decoded - z|`` (0 for lossless modes).
    float_bits : int
        Width of the source float in ``"float"`` and ``"decimal"`` modes.
    bins : int
        ``"quantized"`` mode: the odd width, in codes, of the codec's residual bins (SZ3's
        quantisation of each residual against its prediction from decoded codes: a
        decoded code is the prediction plus a multiple of ``bins``, within ``(bins - 1)
        / 2`` codes of the sample's own). 1: every code decodes to itself
        (``|decoded - z| <= step / 2``); above 1, ``step / 2 + (bins - 1) / 2 · step <=
        codec_error`` and decoded heights depend on the pyramid
        (:func:`geoterrain.codec.pyramid.decoded_codes`).

    Examples
    --------
    >>> Quantizer("int", 1.0, 0.0, 0.0).mode
    'int'
    """

    mode: str
    step: float = 1.0
    offset: float = 0.0
    codec_error: float = 0.0
    float_bits: int = 64
    bins: int = 1

    @classmethod
    def from_json(cls, d: dict) -> Quantizer:
        """From a store's metadata (older stores call ε ``max_error``).

        Examples
        --------
        >>> Quantizer.from_json({"mode": "quantized", "step": 0.9, "max_error": 0.5}).codec_error
        0.5
        """
        d = dict(d)
        if "max_error" in d:
            d.setdefault("codec_error", d.pop("max_error"))
        return cls(**d)

    def to_json(self) -> dict:
        """For a store's metadata: every field, ``bins`` only when above 1 (a store
        without residual bins reads as before; code that predates them refuses one with).

        Examples
        --------
        >>> Quantizer("int").to_json()
        {'mode': 'int', 'step': 1.0, 'offset': 0.0, 'codec_error': 0.0, 'float_bits': 64}
        """
        d = dataclasses.asdict(self)
        if self.bins == 1:
            del d["bins"]
        return d

    def __post_init__(self) -> None:
        if self.mode not in ("int", "decimal", "quantized", "float"):
            raise ValueError(f"unknown quantizer mode {self.mode!r}")
        if self.mode != "float" and not self.step > 0:
            raise ValueError("quantizer step must be > 0")
        if self.float_bits not in (32, 64):
            raise ValueError("float_bits must be 32 or 64")
        if self.mode == "decimal" and (self.offset != 0.0 or self.step not in DECIMAL_STEPS):
            raise ValueError("a decimal quantizer has a step of 10^-d (d = 1 to 4) and offset 0")
        if not (isinstance(self.bins, int) and 1 <= self.bins <= MAX_BINS and self.bins & 1):
            raise ValueError(f"quantizer bins must be an odd integer in 1 … {MAX_BINS}")
        if self.bins > 1 and self.mode != "quantized":
            raise ValueError("only a quantized (lossy) quantizer has residual bins")

    @property
    def divisor(self) -> float:
        """``"decimal"`` mode: 10^d, the exact integer its codes are divided by."""
        return float(round(1.0 / self.step))


def describe_codec(q: Quantizer) -> str:
    """One line saying how heights are coded."""
    if q.mode == "float":
        return f"lossless float{q.float_bits} (bit-exact), residuals + range coder"
    if q.mode == "int":
        return f"lossless integer codes × {q.step:g} + {q.offset:g}, residuals + range coder"
    if q.mode == "decimal":
        places = len(str(int(q.divisor))) - 1  # 10^d
        return (f"lossless decimals ({places} place{'s' * (places > 1)}, rounded to "
                f"float{q.float_bits}) as integer codes, residuals + range coder")
    if q.bins > 1:
        return (f"within ε = {q.codec_error:g}: codes of {q.step:.6g}, residuals in bins of "
                f"{q.bins} codes + range coder")
    return f"quantised to ε = {q.codec_error:g} (step {q.step:.6g}), residuals + range coder"
