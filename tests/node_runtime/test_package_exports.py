"""smm_node_runtime's lazily loaded names: each exported name has one source module and resolves from it."""

from __future__ import annotations

import importlib

import pytest

import smm_node_runtime


def test_every_exported_name_has_a_source_and_no_source_is_unexported() -> None:
    assert set(smm_node_runtime._SOURCES) == set(smm_node_runtime.__all__)


@pytest.mark.parametrize("name", sorted(smm_node_runtime.__all__))
def test_each_name_resolves_to_its_source_modules_object(name: str) -> None:
    source = importlib.import_module(smm_node_runtime._SOURCES[name])
    assert getattr(smm_node_runtime, name) is getattr(source, name)


def test_an_unknown_name_is_an_attribute_error() -> None:
    with pytest.raises(AttributeError, match="no attribute 'NoSuchName'"):
        _ = smm_node_runtime.NoSuchName  # type: ignore[attr-defined]
