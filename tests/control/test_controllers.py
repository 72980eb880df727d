"""Every controller by one name: shipped policies, policy files, module:callable and
file.py:callable, with one-line errors for everything else."""
import numpy as np
import pytest

from twolink.control.controllers import resolve_controller
from twolink.sim.controller import ControllerError

X = np.array([[-1.0, -3.0, 0.0, 0.0], [0.3, -0.2, 0.0, 0.0]])

USER = """
import numpy as np

def pd(x):
    return np.clip(-3.0 * x[:, :2] - 0.6 * x[:, 2:], [-1.5, -0.1], [1.5, 0.1])

class Zero:
    meta = {"model": "full"}
    def __call__(self, x):
        return np.zeros((len(x), 2))

NOT_CALLABLE = 3
"""


@pytest.fixture
def user_file(tmp_path):
    path = tmp_path / "mine.py"
    path.write_text(USER)
    return path


def test_a_shipped_policy_is_found_by_name(centralized):
    c = resolve_controller("centralized")
    np.testing.assert_array_equal(c(X), centralized(X))
    assert c.name == "centralized" and c.meta["model"] == "simplified"


def test_a_file_controller_and_a_class(user_file):
    c = resolve_controller(f"{user_file}:pd")
    np.testing.assert_allclose(c(X), np.clip(-3.0 * X[:, :2], [-1.5, -0.1], [1.5, 0.1]))
    z = resolve_controller(f"{user_file}:Zero")
    assert z(X).shape == (2, 2) and z.meta == {"model": "full"} and z.name == "Zero"


def test_a_module_controller(tmp_path, monkeypatch, user_file):
    monkeypatch.syspath_prepend(str(user_file.parent))
    assert resolve_controller("mine:pd")(X).shape == (2, 2)


@pytest.mark.parametrize("spec, match", [
    ("nosuch", "unknown controller 'nosuch'; give a name of `twolink controllers`"),
    ("lqrr", r"unknown controller 'lqrr' \(did you mean 'lqr'"),
    ("centralised", r"\(did you mean 'centralized'"),
    ("{dir}/missing.py:pd", "missing.py does not exist"),
    ("{file}:nothing", "has no attribute 'nothing'"),
    ("{file}:NOT_CALLABLE", "is not callable"),
    ("no_such_module_xyz:f", "cannot import controller module 'no_such_module_xyz'"),
    ("{file}:", "give module:callable"),
])
def test_bad_names_end_in_one_line(spec, match, user_file):
    with pytest.raises(ControllerError, match=match) as info:
        resolve_controller(spec.format(dir=user_file.parent, file=user_file))
    assert "\n" not in str(info.value)


def test_a_file_that_fails_to_import_is_named(tmp_path):
    bad = tmp_path / "broken.py"
    bad.write_text("def f(:\n")
    with pytest.raises(ControllerError, match=r"cannot import controller file .*broken.py: "
                                              r"SyntaxError"):
        resolve_controller(f"{bad}:f")


def test_absolute_spec_names_the_same_file_from_anywhere(user_file, monkeypatch):
    from twolink.control.controllers import absolute_spec

    monkeypatch.chdir(user_file.parent)
    assert absolute_spec("mine.py:pd") == f"{user_file}:pd"
    assert absolute_spec("./sub/p.npz") == str(user_file.parent / "sub" / "p.npz")
    for same in ("lqr", "centralized", "numpy.linalg:norm", "nope"):
        assert absolute_spec(same) == same
    monkeypatch.chdir("/")
    c = resolve_controller(f"{user_file}:pd")
    assert c(X).shape == (2, 2)
