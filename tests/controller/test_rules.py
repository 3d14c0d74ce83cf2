"""Rule tables as transcribed (Tables 1 and 7) and the worked example R1..R4 of Section III.B."""

from __future__ import annotations

import pytest
from smm_controller.rules import (
    FLESO_BANDWIDTH_RULES,
    PD_LABELS,
    TABLE_1,
    TABLE_7,
    parse_rule_table,
    pd_gain_system,
    pd_input_variable,
)


def cell(table: tuple[tuple[tuple[str, str], ...], ...], ce: str, e: str) -> tuple[str, str]:
    return table[PD_LABELS.index(ce)][PD_LABELS.index(e)]


def test_table_7_equals_table_1_as_transcribed() -> None:
    assert TABLE_7 == TABLE_1
    assert TABLE_7 is not TABLE_1


def test_tables_are_complete_seven_by_seven() -> None:
    assert len(TABLE_1) == 7
    assert all(len(row) == 7 for row in TABLE_1)
    assert all(label in PD_LABELS for row in TABLE_1 for pair in row for label in pair)


@pytest.mark.parametrize(
    ("ce", "e", "expected"),
    [
        ("NB", "NB", ("PB", "PB")),
        ("NB", "ZE", ("NM", "NM")),
        ("NS", "NB", ("PB", "PM")),
        ("NS", "PB", ("PM", "PS")),
        ("ZE", "NB", ("NM", "ZE")),
        ("PM", "PS", ("NM", "NB")),
        ("PB", "ZE", ("PM", "PM")),
    ],
)
def test_spot_cells_against_the_paper(ce: str, e: str, expected: tuple[str, str]) -> None:
    """Rows are ce, columns e (spot checks of the transcription, read off Table 1)."""
    assert cell(TABLE_1, ce, e) == expected


def test_worked_example_fires_exactly_ps_pm_by_ze_ps() -> None:
    variable = pd_input_variable()
    e_active = [PD_LABELS[i] for i, _ in variable.active(0.51)]
    ce_active = [PD_LABELS[i] for i, _ in variable.active(0.20)]
    assert e_active == ["PS", "PM"]
    assert ce_active == ["ZE", "PS"]


def test_worked_example_rules_r1_to_r4() -> None:
    # R1: e=PS, ce=ZE -> PM\NS; R2: e=PS, ce=PS -> NM\NS; R3: e=PM, ce=ZE -> PM\NS; R4: e=PM, ce=PS -> NM\NS.
    assert cell(TABLE_1, "ZE", "PS") == ("PM", "NS")
    assert cell(TABLE_1, "PS", "PS") == ("NM", "NS")
    assert cell(TABLE_1, "ZE", "PM") == ("PM", "NS")
    assert cell(TABLE_1, "PS", "PM") == ("NM", "NS")


def test_worked_example_implication_levels() -> None:
    """PM (f(k_e)) fires at max(min(mu_PS(e), mu_ZE(ce)), min(mu_PM(e), mu_ZE(ce))), etc."""
    system = pd_gain_system(TABLE_1)
    variable = pd_input_variable()
    mu_e = dict(variable.active(0.51))
    mu_ce = dict(variable.active(0.20))
    ps, pm, ze = PD_LABELS.index("PS"), PD_LABELS.index("PM"), PD_LABELS.index("ZE")
    r1, r2 = min(mu_e[ps], mu_ce[ze]), min(mu_e[ps], mu_ce[ps])
    r3, r4 = min(mu_e[pm], mu_ce[ze]), min(mu_e[pm], mu_ce[ps])
    strengths = system.label_strengths((0.51, 0.20))
    n = system.n_labels
    expected_ke = [0.0] * n
    expected_ke[PD_LABELS.index("PM")] = max(r1, r3)
    expected_ke[PD_LABELS.index("NM")] = max(r2, r4)
    expected_kde = [0.0] * n
    expected_kde[PD_LABELS.index("NS")] = max(r1, r2, r3, r4)
    assert strengths[:n] == pytest.approx(expected_ke)
    assert strengths[n:] == pytest.approx(expected_kde)


def test_fleso_rules_as_in_the_paper() -> None:
    assert FLESO_BANDWIDTH_RULES == {"NB": "S", "NS": "M", "ZE": "B", "PS": "M", "PB": "S"}


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("ce\\e NB NM\nNB PB\\PB PB\\PB", "header"),
        (
            "ce\\e " + " ".join(PD_LABELS) + "\n" + "\n".join(f"{r} " + "PB\\PB " * 6 for r in PD_LABELS),
            "cells",
        ),
        (
            "ce\\e " + " ".join(PD_LABELS) + "\n" + "\n".join(f"{r} " + "PB\\XX " * 7 for r in PD_LABELS),
            "unknown",
        ),
    ],
)
def test_parser_rejects_malformed_tables(text: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        parse_rule_table(text)
