"""The mesh generators' registry (setup/generators.py): every entry resolves to a builder and an
estimate, and the schema, the set-up and the limits read the same names and keys."""

from __future__ import annotations

import inspect

import pytest

from polypore.setup.generators import REGISTRY, resolve
from polypore.setup.schema.geometry import GENERATOR_KEYS, GENERATORS


@pytest.mark.parametrize("name", sorted(REGISTRY))
def test_every_generator_builds_and_estimates(name):
    g = REGISTRY[name]
    build, estimate = resolve(g.build), resolve(g.estimate)
    assert callable(build) and callable(estimate)
    params = list(inspect.signature(build).parameters)
    assert params == (["m", "lower", "upper", "specs", "interfaces"] if g.box else ["case", "spec", "t0"]), params
    assert list(inspect.signature(estimate).parameters) == ["spec"]


def test_the_schema_reads_the_registry():
    assert GENERATORS == tuple(REGISTRY)
    assert GENERATOR_KEYS == {k: set(g.keys) for k, g in REGISTRY.items()}


def test_a_missing_function_is_an_error():
    with pytest.raises(AttributeError):
        resolve("limits:cells_nothing")
