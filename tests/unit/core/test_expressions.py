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


# -- bounded evaluation, arithmetic errors, non-finite values (issue 14) ----------------------------
def test_huge_powers_end_quickly_as_input_errors():
    """Python integers made 2**9999999999 and 9**9**9 grow memory without bound: a subprocess with a
    timeout, so that a regression fails instead of hanging the suite."""
    import subprocess
    import sys

    code = ("from polypore.core.expressions import parse\n"
            "from polypore.core.errors import InputError\n"
            "for text in ('2**9999999999', '9**9**9', '(-3)**99999999999', 't**9999999999'):\n"
            "    try:\n"
            "        parse(text, 'f')(t=2)\n"
            "    except InputError as exc:\n"
            "        print(exc)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=30)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert len(lines) == 4 and all(line.startswith("f: expression") and "inf" in line for line in lines), proc.stdout


def _balanced_sum(n: int) -> str:
    """x + x + … with n terms as a balanced tree: many nodes, little depth."""
    return "x" if n == 1 else f"({_balanced_sum(n // 2)}+{_balanced_sum(n - n // 2)})"


@pytest.mark.parametrize("text,msg", [
    ("1/0", "evaluates to inf"),
    ("1 % 0", "evaluates to nan"),
    ("10.0**400", "evaluates to inf"),
    ("log(-1)", "evaluates to nan"),
    ("1e999", "overflows double precision"),
    ("1" + "0" * 400, "overflows double precision"),
    ("+".join(["x"] * 200_000), "too long"),
    (_balanced_sum(1100), "more than 2000 terms"),
    ("+".join(["x"] * 300), "nested more than 200 levels"),
    ("+".join(["x"] * 3000), "nested too deeply"),
    ("-" * 9000 + "1", "nested"),
    ("where(x > 0, 1)", "where takes 3 arguments, got 2"),
])
def test_arithmetic_errors_and_size_limits_name_the_field(text, msg):
    with pytest.raises(InputError, match=msg) as exc:
        parse(text, "mechanics.body_force[1]")
    assert exc.value.field == "mechanics.body_force[1]"
    assert len(str(exc.value)) < 1000     # a 200,000-term text is not echoed back


def test_not_finite_where_evaluated_names_field_and_point():
    e = parse("0.005/x", "mechanics.boundary.ymax.u[1]")    # finite nearly everywhere: parses
    x = np.array([0.5, 0.0, 1.0, 0.0])
    y = np.array([1.0, 1.0, 1.0, 0.5])
    with pytest.raises(InputError) as exc:
        e(x, y, t=3.0)
    assert exc.value.field == "mechanics.boundary.ymax.u[1]"
    assert "not finite at 2 of 4 points" in str(exc.value) and "(x, y) = (0, 1)" in str(exc.value)
    # the variables the expression uses are quoted with the point
    with pytest.raises(InputError, match=r"\(x, y\) = \(1, 0\), t = 2"):
        parse("log(2 - t) * x", "f")(np.array([0.5, 1.0]), np.zeros(2), t=np.array([0.0, 2.0]))
    with pytest.raises(InputError, match="D = 0"):
        parse("1/D", "contact.friction", extra=("D",))(np.zeros(2), np.zeros(2), D=np.array([1.0, 0.0]))
    with pytest.raises(InputError, match="not finite"):
        parse("sqrt(t - 5)", "flow.boundary.xmin.rate")(t=1.0)


def test_discarded_branches_and_truth_values():
    """A division by zero in the branch where() discards is not an error; truth values are 0 and 1."""
    x = np.array([-1.0, 0.0, 2.0])
    assert parse("where(x > 0, 1/x, 0)", "f")(x).tolist() == [0.0, 0.0, 0.5]
    assert parse("-(x > 0) + 2*(x < 0)", "f")(x).tolist() == [2.0, 0.0, -1.0]
    assert parse("2**10 + 7 % 3", "f")() == 1025.0


@pytest.mark.parametrize("params,extra,text,field,msg", [
    ({"x": 1.0}, (), "2*y", "params.x", "coordinate/time variable"),
    ({"t": 1.0}, (), "2", "params.t", "coordinate/time variable"),
    ({"sin": 1.0}, (), "2", "params.sin", "a function"),
    ({"pi": 3.0}, (), "2*pi", "params.pi", "a constant"),
    ({"D": 1.0}, ("D",), "0.5 + D", "params.D", "a variable of contact.friction"),
    ({"rate-1": 1.0}, (), "1", "params.rate-1", "cannot be used in an expression"),
])
def test_parameter_names_that_shadow_are_rejected(params, extra, text, field, msg):
    with pytest.raises(InputError, match=msg) as exc:
        parse(text, "contact.friction", params, extra)
    assert exc.value.field == field
    # a name of the extra variables is fine where the expression does not use it
    assert parse("2*T", "f", {"T": 3.0, "D": 1.0}, ("D",))() == 6.0


@pytest.mark.parametrize("value", [float("inf"), float("nan"), 10**400])
def test_non_finite_numbers_are_rejected(value):
    with pytest.raises(InputError, match="must be a finite number") as exc:
        parse(value, "material.E")
    assert exc.value.field == "material.E"
