"""stylepong_policy.png: the small PNG files every chart and strip is written as."""

import numpy as np
from PIL import Image

from stylepong_policy import png


def _pixels(path):
    with Image.open(path) as image:
        return np.asarray(image.convert('RGB'))


def test_few_colours_are_kept_exactly_and_many_are_quantised(tmp_path):
    rng = np.random.default_rng(0)
    few = rng.choice([0, 128, 255], size=(40, 60, 3)).astype(np.uint8)  # 27 colours at most
    png.write_png(Image.fromarray(few), tmp_path / 'few.png')
    with Image.open(tmp_path / 'few.png') as image:
        assert image.mode == 'P'
    assert np.array_equal(_pixels(tmp_path / 'few.png'), few)
    many = rng.integers(0, 256, size=(40, 60, 3), dtype=np.uint8)
    png.write_png(Image.fromarray(many), tmp_path / 'many.png')
    quantised = _pixels(tmp_path / 'many.png')
    assert len(np.unique(quantised.reshape(-1, 3), axis=0)) <= png.PALETTE_COLOURS


def test_a_transparent_pixel_lies_on_white_and_shrinking_again_changes_nothing(tmp_path):
    rgba = np.zeros((8, 8, 4), dtype=np.uint8)
    rgba[:4, :, :] = (10, 20, 30, 255)
    path = png.write_png(Image.fromarray(rgba, mode='RGBA'), tmp_path / 'a.png')
    assert (_pixels(path)[:4] == (10, 20, 30)).all() and (_pixels(path)[4:] == 255).all()
    many = np.random.default_rng(1).integers(0, 256, size=(30, 30, 3), dtype=np.uint8)
    path = png.write_png(Image.fromarray(many), tmp_path / 'b.png')
    written = path.read_bytes()
    assert png.shrink(path).read_bytes() == written


def test_a_figure_is_saved_small_unless_its_path_names_another_format(tmp_path):
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    figure, ax = plt.subplots(figsize=(3, 2))
    ax.plot([0, 1, 2], [0, 1, 0])
    png.save_figure(figure, tmp_path / 'chart.png', dpi=50)
    png.save_figure(figure, tmp_path / 'chart.pdf', dpi=50)
    plt.close(figure)
    with Image.open(tmp_path / 'chart.png') as image:
        assert image.mode == 'P' and image.size == (150, 100)
    assert (tmp_path / 'chart.pdf').read_bytes().startswith(b'%PDF')
