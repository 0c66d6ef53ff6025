"""Presets (options.PRESETS): they resolve, validate and do what their names promise."""

import numpy as np
import pytest

import isophote
from isophote.encoder.levels import channel_levels
from isophote.errors import OptionError
from isophote.options import AUTO_LOCAL_NOISE, DEFAULT_PRESET, PRESETS, EncodeOptions


@pytest.mark.parametrize("name", list(PRESETS))
def test_every_preset_resolves_with_every_field_filled(name):
    opts = EncodeOptions(preset=name).resolved()
    for field in PRESETS[name]:
        assert getattr(opts, field) is not None, field
    assert set(PRESETS[name]) == set(PRESETS["paper"])  # every preset sets the same fields


def test_the_presets_and_the_default():
    assert {"paper", "high", "compact", "balanced"} <= set(PRESETS)
    assert DEFAULT_PRESET in PRESETS
    assert EncodeOptions().resolved().preset == DEFAULT_PRESET


def test_paper_is_section_1_of_the_paper():
    opts = EncodeOptions(preset="paper").resolved()
    assert len(channel_levels("Y", opts)) == 25 and len(channel_levels("U", opts)) == 49
    assert channel_levels("Y", opts)[12] == 127.5
    assert opts.noise is None and opts.local_noise == 0 and opts.prune_area_y == opts.prune_area_uv == 0
    assert (opts.min_tolerance, opts.max_tolerance, opts.snap) == (0.05, 0.5, 20.0)


def test_level_range_paper_and_full():
    """The paper's levels stop at 7.5 and 247.5; the full range reaches 1.5 and 253.5 in steps
    of 3 (high) and adds nothing to steps of 10, whose next levels would leave the scale."""
    high = EncodeOptions(preset="high").resolved()
    assert high.level_range == (0.5, 254.5)
    y = channel_levels("Y", high)
    assert (y[0], y[-1], len(y)) == (1.5, 253.5, 85)
    assert np.allclose(np.diff(y), 3.0) and 127.5 in y
    paper_range = EncodeOptions(preset="high", level_range=(7.5, 247.5)).resolved()
    assert (channel_levels("Y", paper_range)[0], channel_levels("Y", paper_range)[-1]) == (7.5, 247.5)
    full10 = EncodeOptions(preset="paper", level_range=(0.5, 254.5)).resolved()
    assert np.array_equal(channel_levels("Y", full10), channel_levels("Y", EncodeOptions(preset="paper").resolved()))
    assert len(channel_levels("U", full10)) == 51  # 2.5 and 252.5 join the paper's 49


def test_full_range_traces_dark_shading_the_paper_range_leaves_flat():
    """A ramp from 0 to 12 grey levels: the paper's range has its one level (7.5) there and
    renders the part below it as a cap; the full range adds 1.5 and 4.5 and follows the ramp."""
    h, w = 24, 96
    ramp = np.tile(np.linspace(0.0, 12.0, w), (h, 1))
    img = np.rint(ramp).astype(np.uint8)
    out = {}
    for rng in ((7.5, 247.5), (0.5, 254.5)):
        vi = isophote.encode(img, y_step=3.0, level_range=rng)
        y = vi.channels[0]
        present = np.unique(y.levels[y.contour_level])
        out[rng] = (present, np.abs(vi.render().astype(float) - img).mean())
    assert np.array_equal(out[(7.5, 247.5)][0], [7.5, 10.5])
    assert np.array_equal(out[(0.5, 254.5)][0], [1.5, 4.5, 7.5, 10.5])
    assert out[(0.5, 254.5)][1] < 0.5 * out[(7.5, 247.5)][1]
    assert out[(0.5, 254.5)][1] < 0.5


def test_explicit_fields_override_the_preset():
    opts = EncodeOptions(preset="high", y_step=7.0, local_noise=0.0, max_tolerance=0.25).resolved()
    assert (opts.y_step, opts.local_noise, opts.max_tolerance) == (7.0, 0.0, 0.25)
    assert opts.uv_step == PRESETS["high"]["uv_step"]


def test_noise_auto():
    opts = EncodeOptions(preset="paper", noise="auto").resolved()
    assert opts.noise is None and opts.local_noise == AUTO_LOCAL_NOISE
    assert opts.prune_area_y == opts.prune_area_uv == 0  # auto: the estimate only, the rest is the preset's
    high = EncodeOptions(preset="high", noise="AUTO").resolved()
    assert high.local_noise == PRESETS["high"]["local_noise"]
    assert EncodeOptions(preset="paper", noise="auto", local_noise=2.5).resolved().local_noise == 2.5
    # a number is the sample error everywhere; with local_noise given too, it is the floor
    fixed = EncodeOptions(preset="high", noise=1.5).resolved()
    assert (fixed.noise, fixed.local_noise) == (1.5, 0.0)
    floor = EncodeOptions(preset="paper", noise=1.5, local_noise=2.0).resolved()
    assert (floor.noise, floor.local_noise) == (1.5, 2.0)


def test_noise_floor_accepts_a_number_or_three():
    assert EncodeOptions(noise_floor=2).resolved().noise_floor == (2.0,)
    assert EncodeOptions(noise_floor=[1, 2, 3]).resolved().noise_floor == (1.0, 2.0, 3.0)


@pytest.mark.parametrize("bad", [
    dict(preset="nope"),
    dict(noise="loud"),
    dict(noise=-1.0),
    dict(local_noise=-0.5),
    dict(local_noise=17.0),
    dict(noise_floor=(1.0, 2.0, 3.0, 4.0)),
    dict(noise_floor=(-1.0,)),
    dict(prune_area_y=-4.0),
    dict(prune_area_uv=2e6),
    dict(prune_contrast=-1.0),
    dict(preset="paper", min_tolerance=0.6),  # above paper's max_tolerance 0.5
    dict(level_range=(0.0, 255.0)),  # a level at 0 or 255 would equal a value
    dict(level_range=(200.0, 100.0)),
    dict(level_range=(7.5,)),
    dict(level_range=5.0),
    dict(level_range=(128.0, 129.0)),  # no 127.5 + 10k inside
])
def test_bad_values_are_refused(bad):
    with pytest.raises(OptionError):
        EncodeOptions(**bad).resolved()


def _photo_like(seed=3, h=80, w=112, noise=1.0):
    """Smooth shading, a few sharp shapes and sensor-like noise."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w]
    base = 110 + 70 * np.sin(x / 17.0) * np.cos(y / 23.0)
    base += 50 * ((x - 70) ** 2 + (y - 40) ** 2 < 15**2)
    rgb = np.stack([base, 0.8 * base + 20, 1.1 * base - 30], axis=2)
    return np.clip(rgb + rng.normal(0, noise, rgb.shape), 0, 255).astype(np.uint8)


def test_presets_order_by_size_and_fidelity():
    """compact spends fewer segments than paper; balanced fewer than paper and is more
    faithful; high is the most faithful."""
    img = _photo_like()
    out = {p: isophote.encode(img, preset=p) for p in ("paper", "high", "compact", "balanced")}
    segs = {p: sum(ch.n_segments for ch in vi.channels) for p, vi in out.items()}
    err = {p: float(np.sqrt(np.mean((vi.render().astype(float) - img) ** 2))) for p, vi in out.items()}
    assert segs["compact"] < 0.7 * segs["paper"]
    assert err["high"] < err["paper"]
    assert err["compact"] < 2.0 * err["paper"]
    assert segs["balanced"] < segs["paper"] and err["balanced"] < err["paper"]
    assert err["high"] < err["balanced"]
