"""parsers.diag.labels: every spelling of a register label → one canonical name."""

from __future__ import annotations

import pytest

from parsers.diag.labels import canonical_label, decode_label, repair_encoding


@pytest.mark.parametrize(
    ("label", "canonical"),
    [
        # the ten-character cuts as printed in seed 003
        ("Diagnose I", "diagnosis_info"),
        ("Bezeichnun", "designation"),
        ("Typennum", "type_number"),
        ("Gerätestan", "hardware_state"),
        ("Seriennum", "serial_number"),
        ("CRC-Code", "crc_code"),
        ("Software V", "software_version"),
        ("Diagnose", "diagnosis"),
        ("Radsensor", "wheel_sensor"),
        ("Summenzä", "sum_counter"),
        ("Zähler 4-Fl", "counter_4_edge"),
        ("Zähler 1-Fl", "counter_1_edge"),
        ("Zähler 1-FI", "counter_1_edge"),  # the paper's capital I
        ("Analogwer", "analog_value"),
        # full names, other cuts, case and spacing
        ("Summenzähler", "sum_counter"),
        ("Zähler 1-Flanken", "counter_1_edge"),
        ("ANALOGWERT", "analog_value"),
        ("  Radsensor ", "wheel_sensor"),
        # UTF-8 read as CP1252 (mojibake), whole and cut in the middle of a character
        ("ZÃ¤hler 1-Fl", "counter_1_edge"),
        ("SummenzÃ¤", "sum_counter"),
        ("GerÃ¤testan", "hardware_state"),
        ("SummenzÃ", "sum_counter"),
    ],
)
def test_spellings_map_to_one_name(label: str, canonical: str) -> None:
    assert canonical_label(label) == canonical


@pytest.mark.parametrize("label", ["", "Temperatur", "Zähl", "Zähler", "Dia", "[bold]x"])
def test_unknown_or_ambiguous_labels_are_not_guessed(label: str) -> None:
    assert canonical_label(label) is None


def test_latin1_bytes_decode_as_cp1252() -> None:
    assert decode_label("Summenzä".encode("latin-1")) == ("Summenzä", "cp1252")
    assert decode_label("Summenzä".encode()) == ("Summenzä", "utf-8")


def test_repair_leaves_clean_text_alone() -> None:
    assert repair_encoding("Zähler") == "Zähler"
    assert repair_encoding("ZÃ¤hler") == "Zähler"
