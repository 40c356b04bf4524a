"""Pairs on the floor plan: same kind, within the gate, chosen together for the least total distance."""

import numpy as np

from perception.matching import nearest_pairs


def test_pairs_are_chosen_together_within_the_gate_and_of_one_kind():
    a = np.array([[0.0, 0.0, 0.1], [0.02, 0.0, 0.1], [1.0, 1.0, 0.1]])
    b = np.array([[0.015, 0.0, 0.0], [0.035, 0.0, 0.0], [1.0, 1.0, 0.0]])
    # the nearest first would pair a1-b0 (5 mm) and leave a0 35 mm from b1, past the gate: together, both pair
    pairs = nearest_pairs(a, [0, 0, 1], b, [0, 0, 0], gate_m=0.03)
    assert [(i, j) for i, j, _ in pairs] == [(0, 0), (1, 1)], "a2 is of another kind than b2"
    assert np.allclose([d for _, _, d in pairs], [0.015, 0.015])
    assert nearest_pairs(a, [0, 0, 1], b[:1], [0], gate_m=0.001) == [] and nearest_pairs(a[:0], [], b, [0] * 3, 1) == []
