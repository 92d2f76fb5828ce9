"""The one TOML validator (dopplertof/toml_schema.py) that camera presets and dataset
configurations share: the same mistake reads the same in both, one line naming the file
and the key."""

import os
import re

import pytest

from dopplertof.cameras.preset import PRESET_FOLDER, PresetError, _preset_from
from dopplertof.dataset.config import DatasetError, config_from_mapping
from dopplertof.file_formats import read_toml

DATASET = {"samples": 2, "render": {"resolution": [8, 6], "spp": 4}}


def _preset(section: str, key: str, value):
    data = read_toml(os.path.join(PRESET_FOLDER, "kinect-v2.toml"))
    (data[section] if section else data)[key] = value
    with pytest.raises(PresetError) as info:
        _preset_from(data, "mine.toml")
    return str(info.value)


def _dataset(section: str, key: str, value):
    data = {**DATASET, section: {**DATASET.get(section, {}), key: value}}
    with pytest.raises(DatasetError) as info:
        config_from_mapping(data, "data.toml")
    return str(info.value)


@pytest.mark.parametrize("value, said", [
    ("wide", r"must be a number \(.*\), got 'wide'"),
    (True, r"must be a number \(.*\), got True"),
    (float("inf"), "must be finite, got inf"),
    (-5.0, r"out of range \(.*\), got -5.0"),
])
def test_a_bad_number_reads_the_same_in_a_preset_and_a_dataset_config(value, said):
    preset = _preset("modulation", "contrast", value)
    dataset = _dataset("objects", "spread", value)
    assert re.fullmatch(rf"mine\.toml: modulation\.contrast {said}", preset), preset
    assert re.fullmatch(rf"data\.toml: objects\.spread {said}", dataset), dataset


def test_unknown_and_wrongly_typed_keys_read_the_same_in_both():
    assert _preset("sensor", "adc_bitz", 12) == (
        "mine.toml: unknown key sensor.adc_bitz, did you mean 'adc_bits'?")
    assert _dataset("render", "spq", 4) == (
        "data.toml: unknown key render.spq, did you mean 'spp'?")
    assert _preset("sensor", "adc_bits", 12.5).startswith(
        "mine.toml: sensor.adc_bits must be an integer (ADC resolution), got 12.5")
    assert _dataset("render", "spp", 4.5).startswith(
        "data.toml: render.spp must be an integer (samples per pixel per raw frame), got 4.5")


def test_a_section_that_is_no_table_reads_the_same_in_both():
    data = read_toml(os.path.join(PRESET_FOLDER, "kinect-v2.toml"))
    data["sensor"] = "x"
    with pytest.raises(PresetError, match=r"^mine\.toml: \[sensor\] must be a table, got 'x'$"):
        _preset_from(data, "mine.toml")
    with pytest.raises(DatasetError, match=r"^data\.toml: \[render\] must be a table, got 'x'$"):
        config_from_mapping({**DATASET, "render": "x"}, "data.toml")
