"""Small PNG files: every chart and strip this package writes is kept in the repository, so each is saved
with a palette of at most PALETTE_COLOURS colours and compressed as far as zlib goes.

A chart drawn by matplotlib rarely has more colours than that beyond its anti-aliased edges: an image
with few enough is stored exactly (lossless), one with more (rendered frames, many-line charts) is
quantised without dithering (dithering's noise compresses badly), which leaves the frames' smooth
shading slightly banded and a third to a sixth of the size. Pillow comes with matplotlib.
"""

from __future__ import annotations

import io
import os
import pathlib

import numpy as np

PALETTE_COLOURS = 256
CHART_DPI = 110  # the charts of the reports


def palettised(image):
    """`image` (a PIL image) as a palette image: exact when it has at most PALETTE_COLOURS colours, else
    quantised (fast octree, no dithering). A transparent pixel is laid over white, the figures' ground."""
    from PIL import Image

    if image.mode in ('RGBA', 'LA', 'P', 'PA'):
        rgba = image.convert('RGBA')
        ground = Image.new('RGBA', rgba.size, (255, 255, 255, 255))
        rgb = Image.alpha_composite(ground, rgba).convert('RGB')
    else:
        rgb = image.convert('RGB')
    exact = _exact_palette(rgb)
    if exact is None:
        # Quantised, then given the exact palette's order: the same pixels always make the same file, so
        # shrinking a file this module wrote leaves it as it is.
        exact = _exact_palette(
            rgb.quantize(PALETTE_COLOURS, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE).convert('RGB')
        )
    return exact


def _exact_palette(rgb):
    """An RGB image as a palette image of its own colours in ascending order; None beyond PALETTE_COLOURS."""
    from PIL import Image

    pixels = np.asarray(rgb, dtype=np.uint32)
    # One integer per colour: np.unique on a flat array is far quicker than on rows.
    packed = (pixels[..., 0] << 16) | (pixels[..., 1] << 8) | pixels[..., 2]
    colours, index = np.unique(packed, return_inverse=True)
    if len(colours) > PALETTE_COLOURS:
        return None
    image = Image.fromarray(index.reshape(packed.shape).astype(np.uint8), mode='P')
    image.putpalette(np.stack([colours >> 16, (colours >> 8) & 255, colours & 255], axis=1).astype(np.uint8).tobytes())
    return image


def write_png(image, path: str | os.PathLike) -> pathlib.Path:
    """Save a PIL image as a palettised, optimised PNG at `path` (its folder made); returns the path."""
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    palettised(image).save(path, format='PNG', optimize=True)
    return path


def save_figure(figure, path: str | os.PathLike, dpi: float) -> pathlib.Path:
    """A matplotlib figure as a small PNG (write_png) at `dpi`; the figure is left open. A path not
    ending in .png (a user's --plot out.pdf) is left to matplotlib, which writes the format it names."""
    from PIL import Image

    path = pathlib.Path(path)
    if path.suffix.lower() != '.png':
        path.parent.mkdir(parents=True, exist_ok=True)
        figure.savefig(path, dpi=dpi)
        return path
    buffer = io.BytesIO()
    figure.savefig(buffer, format='png', dpi=dpi)
    buffer.seek(0)
    with Image.open(buffer) as image:
        return write_png(image, path)


def headless_pyplot():
    """matplotlib.pyplot on the Agg backend: charts are drawn where there is no display."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    return plt


def save_chart(
    figure, path: str | os.PathLike, layout_rect: tuple[float, float, float, float] | None = None
) -> pathlib.Path:
    """A report's chart: `figure` laid out tightly (within layout_rect, fractions of the figure: left, bottom,
    right, top; None: all of it), saved as a small PNG at CHART_DPI (save_figure) and closed."""
    figure.tight_layout(rect=layout_rect)
    saved = save_figure(figure, path, dpi=CHART_DPI)
    headless_pyplot().close(figure)
    return saved


def shrink(path: str | os.PathLike) -> pathlib.Path:
    """Rewrite an existing PNG as write_png would have written it (a figure saved before this module)."""
    from PIL import Image

    with Image.open(path) as image:
        image.load()
    return write_png(image, path)
