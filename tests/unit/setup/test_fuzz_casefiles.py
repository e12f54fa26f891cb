"""Property-based fuzzing of case files (issue 14): random mutations of every built-in case and of
``--set`` overrides (tests/casefuzz.py) run through load and set-up; the only outcomes allowed
are success and an InputError naming a field. benchmarks/fuzz_casefiles.py runs 10,000."""

from datetime import timedelta

from hypothesis import HealthCheck, given, settings

from casefuzz import NAMES, _mesh, base_case, mutated_cases, names_a_field, outcome


def test_every_coarse_builtin_sets_up():
    """The starting points of the fuzz: each built-in case, coarsened, sets up cleanly (and warms
    the mesh cache outside the examples' deadline)."""
    for name in NAMES:
        case = base_case(name)
        _mesh(case)
        assert outcome(case) == ("ok", None), name


@settings(max_examples=300, derandomize=True, database=None, deadline=timedelta(seconds=60),
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much])
@given(mutated_cases())
def test_mutated_cases_succeed_or_name_a_field(example):
    case, what = example
    kind, field = outcome(case)
    assert kind == "ok" or names_a_field(field, case), (what, field)
