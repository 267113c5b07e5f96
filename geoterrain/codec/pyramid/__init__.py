"""Residual compression of the height pyramid (geometry-clipmap style).

Seed 000, section 2.9 (Losasso & Hoppe): finer data come from coarser data plus a
residual, ``R_l = T_l - U(T_{l-1})``, and the runtime rebuilds ``T~_l = U(T~_{l-1}) + R~_l``.
Here the pyramid is the vertex-aligned one of ``docs/conventions.md`` (level L keeps
``[::2**L, ::2**L]``, tiles of ``T = 2**t + 1`` samples sharing borders) and the coding
is *closed loop* on integer codes, so errors never accumulate down the pyramid:

1. every height becomes an int64 code ``q`` (:class:`geoterrain.codec.quantize.Quantizer`);
2. the top tile ``(Lmax, 0, 0)`` is coded coarse to fine inside itself: its 4 corners,
   then each level of its own grid from the next coarser one, as below;
3. every finer tile stores only the samples that are new at its level (those not on the
   parent level's grid), as residuals ``q - pred``; ``pred`` is U(.) of
   :mod:`geoterrain.codec.predict` (linear floor-means or 4-point cubic) on the PARENT tile's
   decoded codes. Samples of the parent level are copied. With residual bins W > 1 (a
   lossy quantizer, :attr:`~geoterrain.codec.quantize.Quantizer.bins`) the residual is
   rounded to a multiple of W (SZ3's linear quantisation): the decoded code is
   ``pred + W · round((q - pred) / W)`` and the multiple is what is coded; the top
   tile's own grids use :func:`top_bins`. The decoded codes then depend on the pyramid
   (:func:`decoded_codes` computes them coarse to fine, as the encoder does).

Invalid samples are not coded: their decoded code is their prediction, so they cost
nothing. In the top tile, whose invalid samples every finer tile is predicted from,
they are filled outward from the valid ones after each level of its own grid
(:func:`geoterrain.codec.predict.fill_outward`: linear extrapolations next to the data, then
the mean of the nearer ring; an invalid corner, which is coded, holds that fill of the
source's codes): a DEM padded to 2**n + 1 samples otherwise paid for
its padding's interpolated predictions in every tile along the edge of its data (St
Helens at ε = 2 m: 1 149 bytes, 651 of them below the top tile, against 624 and 269
with the fill).
The residuals are coded by :mod:`geoterrain.codec.entropy` (an adaptive binary range coder
with contexts), afresh in every tile.

One module per job:

- :mod:`~geoterrain.codec.pyramid.layout`: the pyramid's shape (:func:`pyramid_shape`,
  :func:`roots_shape`), the top tile's residual bins (:func:`top_bins`) and a tile
  blob's header (the blob format, version :data:`BLOB_VERSION`).
- :mod:`~geoterrain.codec.pyramid.decoded`: what decoding every tile gives, on the whole
  grid (:func:`decoded_codes`, :func:`decoded_heights`; the top tile's fill; the
  predictor ``"auto"`` picks).
- :mod:`~geoterrain.codec.pyramid.encode`: the encoder (:func:`encode_pyramid`,
  :func:`encode_decoded`; :func:`encode_root` and :func:`encode_child`, a tile at a time).
- :mod:`~geoterrain.codec.pyramid.decode`: the decoder (:func:`decode_tile`,
  :func:`decode_tile_valid`, :func:`tile_valid`, :func:`blob_predictor`).
"""

from geoterrain.codec.pyramid.decode import (
    blob_predictor,
    decode_tile,
    decode_tile_valid,
    tile_valid,
)
from geoterrain.codec.pyramid.decoded import decoded_codes, decoded_heights
from geoterrain.codec.pyramid.encode import (
    encode_child,
    encode_decoded,
    encode_pyramid,
    encode_root,
)
from geoterrain.codec.pyramid.layout import BLOB_VERSION, pyramid_shape, roots_shape, top_bins

__all__ = [
    "BLOB_VERSION",
    "blob_predictor",
    "encode_child",
    "encode_pyramid",
    "encode_root",
    "decode_tile",
    "decode_tile_valid",
    "tile_valid",
    "decoded_codes",
    "decoded_heights",
    "encode_decoded",
    "pyramid_shape",
    "roots_shape",
    "top_bins",
]
