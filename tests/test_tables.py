"""Invariants of the packages' lookup tables (light types and their slots, light families, capture presets,
complexity levels): each table names only entries of the tables it refers to, and two tables that list the
same keys list them in the same order. These used to be `assert`s run at import; here a broken table fails a
test instead of every import of the module (and the checks still run under `python -O`).
"""
from __future__ import annotations

from dataclasses import fields

import pytest

from scenes.camera_sensor import SENSORS
from scenes.lights import LIGHT_TYPES
from wildgen.config import LEVEL_NUMBERS, PRESET_NAMES, PROCEDURAL_KINDS
from wildgen.levels import LEVELS
from wildgen.light_families import LIGHT_FAMILIES, PS_WILD_FAMILIES
from wildgen.presets import PRESETS


@pytest.mark.parametrize("name", list(LIGHT_TYPES))
def test_a_light_type_excludes_only_known_types_and_its_strength_is_one_of_its_fields(name):
    t = LIGHT_TYPES[name]
    assert set(t.excludes) <= set(LIGHT_TYPES), (name, t.excludes)
    assert t.strength in {f.name for f in fields(t)}, (name, t.strength)


def test_every_light_type_has_its_slot_builder_in_the_table_order():
    from scenes.renderer.light_slots import SLOT_BUILDERS

    assert list(SLOT_BUILDERS) == list(LIGHT_TYPES.values())


def test_the_ps_wild_families_are_light_families():
    assert set(PS_WILD_FAMILIES) <= set(LIGHT_FAMILIES), set(PS_WILD_FAMILIES) - set(LIGHT_FAMILIES)


def test_presets_are_the_names_that_preset_accepts_in_the_same_order():
    # --preset lists the names from wildgen.config (GenConfig cannot import its own instances); the two agree.
    assert tuple(PRESETS) == PRESET_NAMES


@pytest.mark.parametrize("name", list(PRESETS))
def test_a_preset_names_only_existing_families_and_sensors_and_is_valid(name):
    config = PRESETS[name].config
    assert set(config.lights) <= set(LIGHT_FAMILIES), (name, config.lights)
    assert config.sensor in SENSORS, (name, config.sensor)
    config.validate()


def test_levels_are_the_numbers_that_level_accepts_in_the_same_order():
    assert tuple(LEVELS) == LEVEL_NUMBERS


@pytest.mark.parametrize("number", list(LEVELS))
def test_a_level_names_only_existing_families_and_shape_kinds_and_is_valid(number):
    config = LEVELS[number].config
    assert set(config.lights) <= set(LIGHT_FAMILIES), (number, config.lights)
    assert set(config.shape_kinds) <= set(PROCEDURAL_KINDS), (number, config.shape_kinds)
    config.validate()
