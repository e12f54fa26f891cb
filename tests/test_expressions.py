import numpy as np
import pytest

from polypore.core.errors import InputError
from polypore.core.expressions import parse


def test_constant_and_vectorised():
    assert parse(3, "a")() == 3.0
    e = parse("1e5 + 1000*9.81*(-y) + where(t < 500, 4*t/2000, 1)", "bc.p")
    y = np.array([-1.0, -2.0])
    v = e(np.zeros(2), y, 0.0, 100.0)
    assert np.allclose(v, 1e5 + 9810 * np.array([1.0, 2.0]) + 0.2)
    assert e.names == {"y", "t"}
    assert parse("sqrt(arctan(25*x))", "f")(x=np.array([1.0]))[0] == pytest.approx(np.sqrt(np.arctan(25)))
    assert parse("x if x > 0 else -x", "f")(x=np.array([-2.0, 3.0])).tolist() == [2.0, 3.0]


@pytest.mark.parametrize("text,msg", [
    ("2 *", "does not parse"),
    ("q + 1", "unknown name 'q'"),
    ("__import__('os')", "not allowed"),
    ("x.real", "not allowed"),
    ("open('f')", "not allowed"),
    ("'a' + x", "only numbers"),
    ("[1, 2]", "not allowed"),
])
def test_rejected(text, msg):
    with pytest.raises(InputError, match=msg) as exc:
        parse(text, "loads.body_force")
    assert exc.value.field == "loads.body_force"
