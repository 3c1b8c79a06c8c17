"""The figures of `derive simulate` draw a long run through its extremes (derive.sim.plots._thin)."""
from __future__ import annotations

import numpy as np

from derive.sim.plots import POINTS, _thin


def test_a_short_line_is_drawn_as_it_is():
    t = np.linspace(0, 1, 2 * POINTS)
    y = np.sin(t)
    tt, yy = _thin(t, y)
    assert tt is t and yy is y


def test_a_long_line_keeps_every_buckets_extremes_in_time_order_and_is_bounded():
    rng = np.random.default_rng(3)
    t = np.arange(300_001) * 1e-4                 # a 30 s run at 0.1 ms (the Kinova starter file)
    y = np.cumsum(rng.standard_normal(t.size))
    y[123_457], y[250_000] = 1e6, -1e6            # single-sample spikes survive
    tt, yy = _thin(t, y)
    assert len(tt) <= 2 * POINTS and np.all(np.diff(tt) >= 0)
    assert yy.max() == 1e6 and yy.min() == -1e6
    size = -(-t.size // POINTS)
    for k in (0, 1234, (t.size - 1) // size):     # each bucket's min and max are drawn (the last: partly padded)
        chunk = y[k * size:(k + 1) * size]
        assert chunk.min() in yy and chunk.max() in yy
