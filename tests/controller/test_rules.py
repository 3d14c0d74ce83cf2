"""Rule tables as transcribed (Tables 1 and 7) and the worked example R1..R4 of Section III.B."""

from __future__ import annotations

import re

import numpy as np
import pytest
from numpy.testing import assert_allclose
from smm_controller.rules import (
    FLESO_BANDWIDTH_RULES,
    PD_LABELS,
    TABLE_1,
    TABLE_7,
    fleso_bandwidth_system,
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


def table_text(table: tuple[tuple[tuple[str, str], ...], ...] = TABLE_1) -> list[list[str]]:
    """The table as text cells: a header row, then one row per ce label."""
    return [["ce\\e", *PD_LABELS]] + [
        [ce, *(f"{a}\\{b}" for a, b in row)] for ce, row in zip(PD_LABELS, table, strict=True)
    ]


def joined(cells: list[list[str]]) -> str:
    return "\n\n".join("  ".join(row) for row in cells)  # blank lines between rows are ignored


def test_parser_reads_its_own_output_back() -> None:
    reversed_rows = tuple(tuple(reversed(row)) for row in TABLE_1)
    assert parse_rule_table(joined(table_text(reversed_rows))) == reversed_rows


def rejects(text: str, message: str) -> None:
    """parse_rule_table raises ValueError with exactly ``message``."""
    with pytest.raises(ValueError, match=f"^{re.escape(message)}$"):
        parse_rule_table(text)


def test_parser_errors_name_what_is_wrong() -> None:
    """A malformed table is rejected with the header, row or cell at fault and what was found."""
    labels = "NB NM NS ZE PS PM PB"
    rejects(" \n\n", "rule table is empty")
    cells = table_text()
    cells[0] = cells[0][:3]
    rejects(joined(cells), f"rule table header must list {labels} in order, got 'NB NM'")
    cells = table_text()
    cells[1], cells[2] = cells[2], cells[1]
    rejects(joined(cells), f"rule table first column must list {labels} in order, got 'NM NB NS ZE PS PM PB'")
    cells = table_text()
    del cells[3][4]
    rejects(joined(cells), "rule table row 'NS' must have 7 cells, got 6")
    cells = table_text()
    cells[3].append("PB\\PB")
    rejects(joined(cells), "rule table row 'NS' must have 7 cells, got 8")
    for cell in ("PB", "PB\\NS\\ZE"):
        cells = table_text()
        cells[3][4] = cell
        rejects(
            joined(cells),
            f"rule table cell {cell} (row NS, column ZE) must be two labels joined by a backslash, "
            "e.g. PB\\NS",
        )
    for cell, unknown in (("PB\\XX", "XX"), ("YY\\NS", "YY"), ("XX\\YY", "XX"), ("PB\\", "")):
        cells = table_text()
        cells[6][1] = cell
        rejects(
            joined(cells),
            f"rule table cell {cell} (row PM, column NB) has unknown label {unknown!r}; labels are {labels}",
        )


@pytest.mark.parametrize("grid_points", [3, 51, 202])
def test_systems_use_the_given_grid(grid_points: int) -> None:
    grid = np.linspace(-1.0, 1.0, grid_points)
    assert_allclose(fleso_bandwidth_system(grid_points).grid, grid, rtol=0.0, atol=0.0)
    assert_allclose(pd_gain_system(TABLE_1, grid_points).grid, grid, rtol=0.0, atol=0.0)
