"""The in-place matrix builder gives what stacking gives."""

import numpy as np

from twin.instruments.arrays import matrices


def test_matrices_are_the_stacked_rows():
    rng = np.random.default_rng(1)
    for shape in [(), (4,), (2, 5)]:
        x, y = rng.normal(size=shape), rng.normal(size=shape)
        rows = [[x, 0.0, -y], [y * x, 1.5, x]]
        full = [[np.broadcast_to(np.asarray(v, float), shape) for v in r] for r in rows]
        stacked = np.stack([np.stack(r, axis=-1) for r in full], axis=-2)
        built = matrices(rows, shape)
        assert built.shape == (*shape, 2, 3)
        assert np.array_equal(built, stacked)
