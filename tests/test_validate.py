import numpy as np
import pytest

from uwbwb import validate


def test_integer():
    assert validate.integer("n", np.int64(3), minimum=1) == 3
    for bad in (2.5, True, "3", None, 0, np.float64(3.0)):
        with pytest.raises(ValueError, match="^n must be an integer >= 1"):
            validate.integer("n", bad, minimum=1)


def test_number_probability_choice():
    assert validate.number("x", np.float32(0.5), minimum=0.0) == 0.5
    for bad in (float("nan"), float("inf"), "1", None, True, -0.1):
        with pytest.raises(ValueError, match="^x must be a finite number"):
            validate.number("x", bad, minimum=0.0)
    assert validate.number("x", float("inf"), allow_inf=True) == float("inf")
    with pytest.raises(ValueError, match="> 0"):
        validate.number("x", 0.0, minimum=0.0, strict_minimum=True)
    assert validate.probability("p", 0.5) == 0.5
    for bad in (0.0, 1.0, float("nan"), "0.5"):
        with pytest.raises(ValueError, match=r"p must be a number in \(0, 1\)"):
            validate.probability("p", bad)
    assert validate.probability("p", 1.0, open_interval=False) == 1.0
    assert validate.choice("m", "a", ("a", "b")) == "a"
    with pytest.raises(ValueError, match="m must be one of 'a', 'b', got 'c'"):
        validate.choice("m", "c", ("a", "b"))


def test_points():
    src = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0]]
    arr = validate.points("anchors", src, minimum=2)
    assert arr.dtype == float and arr.shape == (2, 3)
    arr[0, 0] = 5.0                      # a new array: the caller's value is not touched
    assert src[0][0] == 0.0
    for bad in ([[0.0, 1.0]], [[0.0, 0.0, 1.0]], [1.0, 2.0, 3.0], "abc", [[0.0, 1.0, 2.0], [1.0]]):
        with pytest.raises(ValueError, match=r"^anchors must be an \(n >= 2, 3\) array of points"):
            validate.points("anchors", bad, minimum=2)
