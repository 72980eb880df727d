"""twolink.validate: the shared checks of single values and plain numeric arrays."""
import ast
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from twolink import validate
from twolink.validate import choice, is_real, is_whole, real, real_array, whole, whole_array

NOT_NUMBERS = [True, False, np.True_, "1", None, [1], np.array(1), 1j, np.complex128(1),
               Fraction(1, 2)]


def _message(excinfo) -> str:
    return str(excinfo.value)


# -- predicates ------------------------------------------------------------------------

@pytest.mark.parametrize("v", [0, -3, 7, 2**70, np.int64(2), np.int32(-1), np.uint8(5)])
def test_is_whole_takes_python_and_numpy_integers(v):
    assert is_whole(v) is True


@pytest.mark.parametrize("v", NOT_NUMBERS + [1.0, np.float64(2.0), float("nan")])
def test_is_whole_refuses_bools_floats_and_the_rest(v):
    assert is_whole(v) is False


@pytest.mark.parametrize("v", [0, -2, 0.5, np.int64(3), np.float32(0.5), np.float64(1.5),
                               np.float16(1), float("nan"), float("inf")])
def test_is_real_takes_real_scalars_nan_and_inf_included(v):
    assert is_real(v) is True


@pytest.mark.parametrize("v", NOT_NUMBERS)
def test_is_real_refuses_bools_complex_arrays_and_the_rest(v):
    assert is_real(v) is False


def test_is_real_without_numpy_takes_python_numbers_and_float64_only():
    assert is_real(1, numpy=False) and is_real(0.5, numpy=False)
    assert is_real(np.float64(0.5), numpy=False)          # a subclass of float
    assert not is_real(np.int64(1), numpy=False)
    assert not is_real(np.float32(0.5), numpy=False)
    assert not is_real(True, numpy=False)


# -- whole -----------------------------------------------------------------------------

def test_whole_returns_a_python_int():
    for v in (3, np.int64(3), np.uint16(3)):
        out = whole(v, "n")
        assert out == 3 and type(out) is int


def test_whole_bounds_are_inclusive():
    assert whole(1, "n", 1, 5) == 1 and whole(5, "n", 1, 5) == 5
    assert whole(-7, "n", high=0) == -7 and whole(10**30, "n", 0) == 10**30
    for v in (0, 6):
        with pytest.raises(ValueError):
            whole(v, "n", 1, 5)


@pytest.mark.parametrize("v", [True, False, np.True_, 2.0, np.float64(2), "2", None,
                               np.array(2), float("nan")])
def test_whole_refuses_what_is_not_a_whole_number(v):
    with pytest.raises(ValueError) as e:
        whole(v, "count", 1, 5)
    assert _message(e) == f"count must be a whole number from 1 to 5, got {v!r}"


@pytest.mark.parametrize("low, high, text", [
    (None, None, "seed must be a whole number, got True"),
    (0, None, "seed must be a non-negative whole number, got True"),
    (1, None, "seed must be a positive whole number, got True"),
    (3, None, "seed must be a whole number of at least 3, got True"),
    (None, 9, "seed must be a whole number of at most 9, got True"),
    (2, 200, "seed must be a whole number from 2 to 200, got True"),
])
def test_whole_default_messages(low, high, text):
    with pytest.raises(ValueError) as e:
        whole(True, "seed", low, high)
    assert _message(e) == text


def test_whole_message_template_fields():
    with pytest.raises(ValueError) as e:
        whole(0, "arms", 1, 10**8, message="{what} must be a whole number in [{low}, {high:,}], "
                                           "got {value!r}")
    assert _message(e) == "arms must be a whole number in [1, 100,000,000], got 0"
    with pytest.raises(ValueError) as e:
        whole("x", "delay", message="{what}: {value} is no count")
    assert _message(e) == "delay: x is no count"


# -- real ------------------------------------------------------------------------------

def test_real_returns_a_python_float():
    for v in (2, 0.25, np.int64(2), np.float32(0.25), np.float64(0.25)):
        out = real(v, "x")
        assert out == float(v) and type(out) is float


@pytest.mark.parametrize("v", [float("nan"), float("inf"), float("-inf"), np.float32("nan"),
                               np.float64("inf"), 10**400, -10**400])
def test_real_refuses_nan_infinities_and_ints_beyond_the_floats(v):
    with pytest.raises(ValueError) as e:
        real(v, "horizon")
    assert _message(e) == f"horizon must be a finite number, got {v!r}"


@pytest.mark.parametrize("v", NOT_NUMBERS)
def test_real_refuses_bools_and_non_numbers(v):
    with pytest.raises(ValueError) as e:
        real(v, "delay")
    assert _message(e) == f"delay must be a finite number, got {v!r}"


def test_real_bounds_closed_and_open():
    assert real(0, "g", 0, 1) == 0.0 and real(1, "g", 0, 1) == 1.0
    assert real(0.5, "g", 0, 1, open_low=True, open_high=True) == 0.5
    for v, kw in ((0, {"open_low": True}), (1, {"open_high": True}), (-0.1, {}), (1.1, {})):
        with pytest.raises(ValueError):
            real(v, "g", 0, 1, **kw)
    assert real(-5, "t", high=0) == -5.0 and real(1e300, "t", 0) == 1e300
    with pytest.raises(ValueError):
        real(0, "t", 0, open_low=True)


@pytest.mark.parametrize("low, high, kw, text", [
    (0.0, 1.0, {}, "gamma must be a number in [0, 1], got nan"),
    (0.0, 1.0, {"open_low": True, "open_high": True}, "gamma must be a number in (0, 1), got nan"),
    (0.0, 1e10, {"open_high": True}, "gamma must be a number in [0, 1e+10), got nan"),
    (0, None, {}, "gamma must be a finite non-negative number, got nan"),
    (0, None, {"open_low": True}, "gamma must be a finite positive number, got nan"),
    (2.5, None, {}, "gamma must be a finite number >= 2.5, got nan"),
    (None, 3, {"open_high": True}, "gamma must be a finite number < 3, got nan"),
])
def test_real_default_messages(low, high, kw, text):
    with pytest.raises(ValueError) as e:
        real(float("nan"), "gamma", low, high, **kw)
    assert _message(e) == text


def test_real_without_numpy_refuses_numpy_integers_and_float32():
    assert real(np.float64(0.5), "tol", 0, 1, numpy=False) == 0.5
    for v in (np.int64(0), np.float32(0.5)):
        with pytest.raises(ValueError) as e:
            real(v, "tol", 0, 1, open_high=True, numpy=False)
        assert _message(e) == f"tol must be a number in [0, 1), got {v!r}"


def test_real_message_template():
    with pytest.raises(ValueError) as e:
        real(0.9, "spread", 0.0, 0.9, open_high=True,
             message="{what} must be a relative change in [0, {high}), got {value!r}")
    assert _message(e) == "spread must be a relative change in [0, 0.9), got 0.9"


# -- choice ----------------------------------------------------------------------------

def test_choice_returns_the_string():
    assert choice("box", "actions", ("box", "discrete")) == "box"
    assert choice("a", "x", {"a": 1, "b": 2}) == "a"         # a dict's keys


@pytest.mark.parametrize("v", ["Box", "", None, 1, ["box"], np.array("box")])
def test_choice_refuses_other_values_and_non_strings(v):
    with pytest.raises(ValueError) as e:
        choice(v, "actions", ("box", "discrete"))
    assert _message(e) == f"actions must be one of 'box', 'discrete', got {v!r}"


def test_choice_message_template():
    with pytest.raises(ValueError) as e:
        choice("x", "task", ["centralized", "decentralized"],
               message="unknown {what} {value!r}; choose one of {choices}")
    assert _message(e) == "unknown task 'x'; choose one of centralized, decentralized"


# -- arrays ----------------------------------------------------------------------------

def test_real_array_converts_and_checks():
    out = real_array([1, 2], "q")
    assert out.dtype == np.float64 and out.tolist() == [1.0, 2.0]
    kept = real_array(np.array([1, 2], dtype=np.int32), "a", dtype=None, finite=False)
    assert kept.dtype == np.int32
    assert np.isnan(real_array([np.nan], "a", finite=False)).all()
    with pytest.raises(ValueError) as e:
        real_array([True], "q")
    assert _message(e) == "q must hold real numbers, got dtype bool"
    with pytest.raises(ValueError) as e:
        real_array(["a"], "q")
    assert _message(e) == "q must hold real numbers, got dtype <U1"
    with pytest.raises(ValueError) as e:
        real_array([1.0, np.inf], "agent a: Q")
    assert _message(e) == "agent a: Q contains NaN or infinite values"


def test_whole_array_takes_counts_as_ints():
    out = whole_array([0, 2.0, 3], "delay")
    assert out.dtype.kind == "i" and out.tolist() == [0, 2, 3]
    assert whole_array(1, "delay").tolist() == 1
    for v in (-1, 0.5, [1, np.nan], np.inf):
        with pytest.raises(ValueError) as e:
            whole_array(v, "delay")
        assert _message(e) == f"delay must hold non-negative whole numbers, got {v}"
    with pytest.raises(ValueError) as e:
        whole_array([1, -2], "observation delay",
                    message="{what} must be a non-negative whole number of samples, got {value}")
    assert _message(e) == ("observation delay must be a non-negative whole number of samples, "
                           "got [1, -2]")


# -- the module and its users ----------------------------------------------------------

def test_validate_imports_only_the_standard_library_and_numpy():
    tree = ast.parse(Path(validate.__file__).read_text())
    roots = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            roots |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            assert node.level == 0
            roots.add(node.module.split(".")[0])
    assert roots - {"numpy", "__future__"} <= set(sys.stdlib_module_names), roots


def test_callers_keep_their_messages():
    from twolink.arm.parameters import check_links
    from twolink.synthesis.problems import check_robust
    from twolink.sim.challenges import MAX_PLANTS, draw_plants
    from twolink.sim.perturbations import ActuationDelay, ObservationDelay

    with pytest.raises(ValueError) as e:
        check_links(True)
    assert _message(e).startswith("links must be a whole number from 2 to ")
    assert _message(e).endswith(", got True")
    assert check_links(np.int64(3)) == 3
    with pytest.raises(ValueError) as e:
        draw_plants(0.1, 0, 0)
    assert _message(e) == f"count must be a whole number of plants from 1 to {MAX_PLANTS}, got 0"
    with pytest.raises(ValueError) as e:
        draw_plants(0.1, 1, -1)
    assert _message(e) == "seed must be a non-negative whole number, got -1"
    with pytest.raises(ValueError) as e:
        check_robust("worst", 2, float("nan"), 0)
    assert _message(e) == "spread must lie in [0, 0.9), got nan"
    assert check_robust("worst", np.int64(2), 0.1, np.int64(4)) == ("worst", 2, 0.1, 4)
    with pytest.raises(ValueError) as e:
        ActuationDelay(None, 1.5)
    assert _message(e) == "delay must be a non-negative whole number of samples, got 1.5"
    with pytest.raises(ValueError) as e:
        ObservationDelay(-1)
    assert _message(e) == "observation delay must be a non-negative whole number of samples, got -1"


def test_in_range_names_the_option_its_bounds_and_meaning():
    from twolink.validate import in_range

    assert in_range(np.float32(0.5), "w", (0.0, 1.0), "a weight") == 0.5
    for bad in (1.5, -0.1, float("nan"), "0.5", True):
        with pytest.raises(ValueError) as e:
            in_range(bad, "w", (0.0, 1.0), "a weight")
        assert _message(e) == f"w must be a number from 0 to 1 (a weight), got {bad!r}"
