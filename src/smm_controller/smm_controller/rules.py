"""Fuzzy variables and rule bases of the paper, as data (SPEC section 4, Tables 1 and 7, Figs 5, 9).

The fuzzy PD gain schedule (two inputs e~, ce~; rows of the tables are ce, columns e) and the FLESO
bandwidth (one input); labels, centres and widths: docs/DESIGN.md, "Rule bases".
"""

from __future__ import annotations

import math

from smm_controller.fuzzy import FuzzyVariable, GaussianMF, MamdaniSystem, TriangularMF

__all__ = [
    "FLESO_BANDWIDTH_RULES",
    "FLESO_INPUT_LABELS",
    "FLESO_OUTPUT_LABELS",
    "PD_LABELS",
    "TABLE_1",
    "TABLE_7",
    "RuleTable",
    "fleso_bandwidth_system",
    "fleso_input_variable",
    "fleso_output_variable",
    "parse_rule_table",
    "pd_gain_system",
    "pd_input_variable",
    "pd_output_variable",
]

#: Labels of both inputs and both outputs of the fuzzy PD schedule, from negative big to positive big.
PD_LABELS: tuple[str, ...] = ("NB", "NM", "NS", "ZE", "PS", "PM", "PB")
FLESO_INPUT_LABELS: tuple[str, ...] = ("NB", "NS", "ZE", "PS", "PB")
FLESO_OUTPUT_LABELS: tuple[str, ...] = ("S", "M", "B")

#: Standard deviation at which a Gaussian is 0.5 at distance ``d`` from its centre is d/sqrt(2 ln 2).
_HALF_CROSSING = math.sqrt(2.0 * math.log(2.0))

#: Cell text "A\B": A is the label of f(k_e), B the label of f(k_de).
#: Rows and columns both in PD_LABELS order.
RuleTable = tuple[tuple[tuple[str, str], ...], ...]

# Table 1 (alpha), transcribed from the paper; rows ce, columns e.
_TABLE_1_TEXT = r"""
ce\e  NB     NM     NS     ZE     PS     PM     PB
NB    PB\PB  PB\PB  PB\PB  NM\NM  PS\PS  PS\PS  ZE\ZE
NM    PB\PB  PB\PB  PB\PB  NS\NM  PS\PS  ZE\ZE  PS\PS
NS    PB\PM  PB\PM  PM\PM  NS\NM  ZE\ZE  PS\PS  PM\PS
ZE    NM\ZE  NM\NS  NM\NS  ZE\ZE  PM\NS  PM\NS  PM\ZE
PS    NM\NS  NS\NS  ZE\ZE  PS\PM  NM\NS  NM\NS  NM\NS
PM    NS\NS  ZE\ZE  NS\NS  PS\PM  NM\NB  NB\NB  NB\NB
PB    ZE\ZE  NS\NS  NM\NM  PM\PM  NB\NB  NB\NB  NB\NB
"""

# Table 7 (beta, Appendix B), transcribed separately; it is identical to Table 1 (a test pins that).
_TABLE_7_TEXT = r"""
ce\e  NB     NM     NS     ZE     PS     PM     PB
NB    PB\PB  PB\PB  PB\PB  NM\NM  PS\PS  PS\PS  ZE\ZE
NM    PB\PB  PB\PB  PB\PB  NS\NM  PS\PS  ZE\ZE  PS\PS
NS    PB\PM  PB\PM  PM\PM  NS\NM  ZE\ZE  PS\PS  PM\PS
ZE    NM\ZE  NM\NS  NM\NS  ZE\ZE  PM\NS  PM\NS  PM\ZE
PS    NM\NS  NS\NS  ZE\ZE  PS\PM  NM\NS  NM\NS  NM\NS
PM    NS\NS  ZE\ZE  NS\NS  PS\PM  NM\NB  NB\NB  NB\NB
PB    ZE\ZE  NS\NS  NM\NM  PM\PM  NB\NB  NB\NB  NB\NB
"""


def parse_rule_table(text: str) -> RuleTable:
    r"""Parses a 7x7 rule table whose header row and first column list PD_LABELS in order.

    Args:
        text: Header line ``ce\e NB ... PB`` then one line per ce label with seven ``A\B`` cells.

    Returns:
        ``table[row][column] = (f(k_e) label, f(k_de) label)``, rows ce, columns e.

    Raises:
        ValueError: naming the header, row or cell that is wrong and what was found.
    """
    lines = [line.split() for line in text.splitlines() if line.strip()]
    if not lines:
        raise ValueError("rule table is empty")
    header, body = lines[0], lines[1:]
    expected = " ".join(PD_LABELS)
    if tuple(header[1:]) != PD_LABELS:
        raise ValueError(f"rule table header must list {expected} in order, got {' '.join(header[1:])!r}")
    rows = tuple(row[0] for row in body)
    if rows != PD_LABELS:
        raise ValueError(f"rule table first column must list {expected} in order, got {' '.join(rows)!r}")
    table = []
    for row in body:
        if len(row) != len(PD_LABELS) + 1:
            raise ValueError(
                f"rule table row {row[0]!r} must have {len(PD_LABELS)} cells, got {len(row) - 1}"
            )
        cells = []
        for column, cell in enumerate(row[1:]):
            where = f"rule table cell {cell} (row {row[0]}, column {PD_LABELS[column]})"
            labels = cell.split("\\")
            if len(labels) != 2:
                raise ValueError(f"{where} must be two labels joined by a backslash, e.g. PB\\NS")
            gain_e, gain_de = labels
            unknown = [label for label in labels if label not in PD_LABELS]
            if unknown:
                raise ValueError(f"{where} has unknown label {unknown[0]!r}; labels are {expected}")
            cells.append((gain_e, gain_de))
        table.append(tuple(cells))
    return tuple(table)


#: Rules for f^alpha(k_e) \ f^alpha(k_de) (paper Table 1); TABLE_1[ce][e].
TABLE_1: RuleTable = parse_rule_table(_TABLE_1_TEXT)
#: Rules for f^beta(k_e) \ f^beta(k_de) (paper Table 7); TABLE_7[ce][e].
TABLE_7: RuleTable = parse_rule_table(_TABLE_7_TEXT)

#: FLESO bandwidth rules: input label -> output label.
FLESO_BANDWIDTH_RULES: dict[str, str] = {"NB": "S", "NS": "M", "ZE": "B", "PS": "M", "PB": "S"}


def _centres(count: int) -> list[float]:
    return [-1.0 + 2.0 * i / (count - 1) for i in range(count)]


def pd_input_variable() -> FuzzyVariable:
    """e~ or ce~: seven triangles of half-width 1/3 centred at -1, -2/3, ..., 1."""
    half_width = 1.0 / 3.0
    return FuzzyVariable(
        PD_LABELS,
        [TriangularMF(c - half_width, c, c + half_width) for c in _centres(len(PD_LABELS))],
    )


def pd_output_variable() -> FuzzyVariable:
    """f(k_e) or f(k_de): seven Gaussians centred at -1, ..., 1, crossing at 0.5 midway."""
    sigma = (1.0 / 6.0) / _HALF_CROSSING
    return FuzzyVariable(PD_LABELS, [GaussianMF(c, sigma) for c in _centres(len(PD_LABELS))])


def fleso_input_variable() -> FuzzyVariable:
    """k_s1 E + k_s2 E': five Gaussians at -1, -0.5, 0, 0.5, 1 crossing at 0.5 midway."""
    sigma = 0.25 / _HALF_CROSSING
    return FuzzyVariable(
        FLESO_INPUT_LABELS, [GaussianMF(c, sigma) for c in _centres(len(FLESO_INPUT_LABELS))]
    )


def fleso_output_variable() -> FuzzyVariable:
    """f(w): Gaussians S, M, B at -1, 0, 1 crossing at 0.5 midway."""
    sigma = 0.5 / _HALF_CROSSING
    return FuzzyVariable(
        FLESO_OUTPUT_LABELS, [GaussianMF(c, sigma) for c in _centres(len(FLESO_OUTPUT_LABELS))]
    )


def pd_gain_system(table: RuleTable, grid_points: int = 201) -> MamdaniSystem:
    """Fuzzy PD gain system: inputs (e~, ce~), outputs (f(k_e), f(k_de)).

    Args:
        table: Rule table, rows ce, columns e (TABLE_1 for alpha, TABLE_7 for beta).
        grid_points: Defuzzification grid size over [-1, 1], >= 3.

    Returns:
        The system; ``evaluate((e~, ce~))`` returns ``(f(k_e), f(k_de))``.
    """
    rules: dict[tuple[str, ...], tuple[str, ...]] = {
        (e_label, ce_label): table[row][column]
        for row, ce_label in enumerate(PD_LABELS)
        for column, e_label in enumerate(PD_LABELS)
    }
    inputs = (pd_input_variable(), pd_input_variable())
    outputs = (pd_output_variable(), pd_output_variable())
    return MamdaniSystem(inputs, outputs, rules, grid_points=grid_points)


def fleso_bandwidth_system(grid_points: int = 201) -> MamdaniSystem:
    """FLESO bandwidth system: input k_s1 E + k_s2 E' (clipped), output f(w)."""
    rules: dict[tuple[str, ...], tuple[str, ...]] = {
        (label,): (FLESO_BANDWIDTH_RULES[label],) for label in FLESO_INPUT_LABELS
    }
    return MamdaniSystem(
        (fleso_input_variable(),), (fleso_output_variable(),), rules, grid_points=grid_points
    )
