"""Text and markdown tables, and the report of a controller comparison (see :mod:`scenarios.experiments.compare`).

:func:`markdown_table` and :func:`text_table` are the table helpers of every report of the
package (the comparison here, the paper reproduction in :mod:`scenarios.experiments.reproduce`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from pinn_mpc.records import RcSummary
from scenarios.records import CompareRow, PredictionRow, RunKpis

if TYPE_CHECKING:
    from scenarios.fleets.fleet import FleetResult

__all__ = [
    "DISCOMFORT_TEXT",
    "KPI_COLUMNS",
    "RC_ROWS",
    "discomfort_text",
    "format_fleet",
    "format_kpis",
    "kpi_columns",
    "kpi_table_text",
    "markdown_table",
    "objective_ratios",
    "rc_table_markdown",
    "reference_of",
    "render_report",
    "text_table",
    "ZONES_TEXT",
    "ZONE_PREDICTION_TEXT",
    "ZONE_RC_ROWS",
    "ZONE_RC_TEXT",
    "zone_kpi_table_markdown",
    "zone_prediction_markdown",
    "zone_rc_table_markdown",
]

#: Prefix of a row's objective divided by the reference controller's.
_RATIO_PREFIX = "objective_to_"
#: (row key, column header, format) of the KPI tables.
KPI_COLUMNS = (
    ("objective", "objective EUR", "{:.3f}"),
    ("objective_to_oracle", "/ oracle", "{:.3f}"),
    ("own_decisions_share", "own decisions", "{:.0%}"),
    ("cost_eur", "cost EUR", "{:.3f}"),
    ("energy_kwh", "energy kWh", "{:.2f}"),
    ("discomfort_avoidable_kh", "avoidable discomfort K h", "{:.3f}"),
    ("discomfort_unavoidable_kh", "unavoidable discomfort K h", "{:.3f}"),
    ("discomfort_kh", "total discomfort K h", "{:.3f}"),
    ("peak_kw", "peak kW", "{:.2f}"),
    ("decision_ms_median", "decision ms (median)", "{:.3g}"),
    ("decision_ms_p95", "decision ms (p95)", "{:.3g}"),
    ("time_ratio", "time ratio", "{:.2e}"),
    ("backup_overrides", "overrides", "{}"),
    ("fallbacks", "fallbacks", "{}"),
)

#: What the ratio column of a report means, by reference controller.
_REFERENCE_TEXT = {
    "oracle": "`/ oracle` divides each objective by the oracle's (true parameters, true T_m, "
    "perfect forecasts).",
    "thermostat": "`/ thermostat` divides each objective by the thermostat's: this plant has "
    "no true parameters or state, so no oracle bound exists and the baseline is the "
    "thermostat (as BOPTEST reports controllers against a building's baseline control).",
}

#: (rc_summary key, label, scale, unit) of the RC parameter table.
RC_ROWS = (
    ("R_ra_K_per_W", "R_ra", 1e3, "mK/W"),
    ("R_rm_K_per_W", "R_rm", 1e3, "mK/W"),
    ("C_r_J_per_K", "C_r", 1e-6, "MJ/K"),
    ("C_m_J_per_K", "C_m", 1e-6, "MJ/K"),
    ("eta", "eta", 1.0, "-"),
    ("solar_aperture_m2", "solar aperture", 1.0, "m2"),
)


#: What a KPI table shows for a key whose value is None, where "n/a" would mislead.
_MISSING = {
    "discomfort_avoidable_kh": "not computed",
    "discomfort_unavoidable_kh": "not computed",
}

#: What the discomfort columns of a report mean.
DISCOMFORT_TEXT = (
    "Discomfort is split in two: the unavoidable part is the too-warm discomfort the same days "
    "gave with the heater off from the same warm-up (for a cooling machine, too cold with it "
    "off), which no controller of this actuator could have avoided; the avoidable part, the "
    "rest, is what a controller is judged on. The total, their sum, is what the objective "
    "counts."
)


def _cell(value: Any, fmt: str, missing: str = "n/a") -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return missing
    return fmt.format(value)


def _kpi_cells(row: Mapping[str, Any], columns: Sequence[tuple[str, str, str]]) -> list[str]:
    return [_cell(row.get(k), f, _MISSING.get(k, "n/a")) for k, _, f in columns]


def objective_ratios(rows: Sequence[RunKpis], *, reference: str) -> list[float | None]:
    """Each row's objective divided by that of the row labelled ``reference`` (None if absent
    or not positive)."""
    ref = next((r["objective"] for r in rows if r["controller"] == reference), None)
    if ref is None or not ref > 0:
        return [None] * len(rows)
    return [float(r["objective"]) / ref for r in rows]


def text_table(headers: Sequence[str], body: Sequence[Sequence[str]]) -> str:
    """Fixed-width table for a terminal: first column left-aligned, the others right-aligned."""
    widths = [max(len(line[i]) for line in [headers, *body]) for i in range(len(headers))]

    def fmt(line: Sequence[str]) -> str:
        first = line[0].ljust(widths[0])
        return "  ".join([first, *(c.rjust(w) for c, w in zip(line[1:], widths[1:], strict=True))])

    return "\n".join(fmt(line) for line in [headers, *body])


def markdown_table(headers: Sequence[str], body: Sequence[Sequence[str]]) -> list[str]:
    """A markdown (GitHub) table as lines: header, separator, one line per body row."""
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(line) + " |" for line in body]
    return lines


def reference_of(rows: Sequence[RunKpis]) -> str:
    """The controller the rows' objectives are divided by: the key ``objective_to_NAME`` a
    row holds (``oracle`` when none does)."""
    keys = (k for r in rows for k in r if k.startswith(_RATIO_PREFIX))
    return next(keys, f"{_RATIO_PREFIX}oracle").removeprefix(_RATIO_PREFIX)


def kpi_columns(rows: Sequence[RunKpis]) -> tuple[tuple[str, str, str], ...]:
    """:data:`KPI_COLUMNS` with the ratio column of the rows' reference (:func:`reference_of`)."""
    ref = reference_of(rows)
    return tuple(
        (f"{_RATIO_PREFIX}{ref}", f"/ {ref}", f) if k.startswith(_RATIO_PREFIX) else (k, h, f)
        for k, h, f in KPI_COLUMNS
    )


def kpi_table_text(rows: Sequence[RunKpis]) -> str:
    """Fixed-width KPI table for a terminal, one line per controller."""
    columns = kpi_columns(rows)
    headers = ["controller", *(h for _, h, _ in columns)]
    body = [[str(r["controller"]), *_kpi_cells(r, columns)] for r in rows]
    return text_table(headers, body)


def _prediction_cells(rows: Sequence[PredictionRow]) -> tuple[list[str], list[list[str]]]:
    horizons = list(dict.fromkeys(h for r in rows for h in r.get("T_r_mae_by_horizon_c", {})))
    headers = ["model", "kind", *(f"MAE {h} [K]" for h in horizons), "T_r bias [K]", "starts"]
    body = [
        [
            str(r["model"]),
            str(r["kind"]),
            *(_cell(r.get("T_r_mae_by_horizon_c", {}).get(h), "{:.3f}") for h in horizons),
            _cell(r["T_r_bias_c"], "{:+.3f}"),
            str(r["n_starts"]),
        ]
        for r in rows
    ]
    return headers, body


def prediction_table_text(rows: Sequence[PredictionRow]) -> str:
    """The prediction errors as a plain-text table (the CLI's summary)."""
    return text_table(*_prediction_cells(rows)) if rows else ""


def rc_table_markdown(rc: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """RC parameters of each source (columns) against each other, plus time constants."""
    sources = list(rc)
    body = []
    for key, label, scale, unit in RC_ROWS:
        cells = [
            _cell(float(rc[s][key]) * scale if key in rc[s] else None, "{:.4g}") for s in sources
        ]
        body.append([f"{label} [{unit}]", *cells])
    for which in ("fast", "slow"):
        cells = [_cell(rc[s].get("time_constants_h", {}).get(which), "{:.3g}") for s in sources]
        body.append([f"time constant, {which} [h]", *cells])
    return markdown_table(["parameter", *sources], body)


#: The report's words on a building of several zones' KPIs per zone.
ZONES_TEXT = (
    "Each zone's discomfort, too cold / too warm [K h] against its own band, and the energy "
    "its actuators delivered [kWh]; the KPI table above gives the building's (the sum over "
    "the zones)."
)
#: The report's words on the prediction of a building of several zones ({h}: main horizon).
ZONE_PREDICTION_TEXT = (
    "Each model predicts every zone's room temperature from the same starts of held-out data "
    "(test part of the weather, the training data's policy, not the closed loop), rolled on "
    "the data's delivered powers and weather (see `scenarios.experiments.compare_zones`): the "
    "learned models and the ARX from the measured rooms, the hybrid and each RC (identified, "
    "learned by a paper network, the true building's where the plant has one) from a Kalman "
    "estimate of their state at the start. MAE over the zones by intervals ahead, bias "
    "(prediction - truth) and each zone's MAE {h} intervals ahead."
)
#: The report's words on the RC values of a building of several zones.
ZONE_RC_TEXT = (
    "Each zone's 2R2C and each internal wall's conductance: the true building (where the plant "
    "has one), the multi-zone RC identified from the training data (grey-box, T_m hidden) and "
    "the RC each paper network of every zone learned (PhysNet, PhysReg)."
)
#: Each zone's RC values as the report gives them: (key, label, scale, unit).
ZONE_RC_ROWS = (
    ("r_ra_k_per_w", "R_ra", 1e3, "mK/W"),
    ("r_rm_k_per_w", "R_rm", 1e3, "mK/W"),
    ("c_r_j_per_k", "C_r", 1e-6, "MJ/K"),
    ("c_m_j_per_k", "C_m", 1e-6, "MJ/K"),
)


def zone_kpi_table_markdown(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """Each controller's discomfort too cold / too warm [K h] and energy [kWh] per zone."""
    zones = list(dict.fromkeys(z for r in rows for z in r.get("zones", {})))
    body = []
    for r in rows:
        cells = []
        for zone in zones:
            z = r.get("zones", {}).get(zone)
            cells.append("n/a" if z is None else (
                f"{z['discomfort_too_cold_kh']:.2f} / {z['discomfort_too_warm_kh']:.2f}, {z['energy_kwh']:.1f} kWh"
            ))
        body.append([f"`{r['controller']}`", *cells])
    return markdown_table(["controller", *(f"{z}: cold / warm K h, energy" for z in zones)], body)


def zone_prediction_markdown(rows: Sequence[PredictionRow]) -> list[str]:
    """The prediction table of a building of several zones: :func:`_prediction_cells` and
    each zone's MAE at the main horizon."""
    headers, body = _prediction_cells(rows)
    zones = list(dict.fromkeys(z for r in rows for z in r.get("T_r_mae_by_zone_c", {})))
    for line, r in zip(body, rows, strict=True):
        line += [_cell(r.get("T_r_mae_by_zone_c", {}).get(z), "{:.3f}") for z in zones]
    return markdown_table([*headers, *(f"{z} [K]" for z in zones)], body)


def zone_rc_table_markdown(zone_rc: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """Each zone's R and C and each wall's conductance (rows) of each source (columns)."""
    sources = list(zone_rc)
    zones = list(dict.fromkeys(z for s in sources for z in zone_rc[s]["zones"]))
    walls = list(dict.fromkeys(w for s in sources for w in zone_rc[s]["walls"]))
    body = []
    for zone in zones:
        for key, label, scale, unit in ZONE_RC_ROWS:
            values = [zone_rc[s]["zones"].get(zone, {}).get(key) for s in sources]
            body.append([f"{zone} {label} [{unit}]",
                         *(_cell(None if v is None else v * scale, "{:.4g}") for v in values)])
    for wall in walls:  # a source without the wall has none: its conductance 0
        body.append([f"wall {wall} U [W/K]", *(_cell(zone_rc[s]["walls"].get(wall, 0.0), "{:.4g}") for s in sources)])
    return markdown_table(["parameter", *sources], body)


def render_report(
    *,
    scenario: str,
    description: str,
    rows: Sequence[CompareRow],
    rc: Mapping[str, RcSummary],
    settings: Mapping[str, Any],
    figure_name: str,
    dates: str,
    notes: Sequence[str] = (),
    prediction: Sequence[PredictionRow] = (),
    prediction_horizon: int = 24,
    zone_rc: Mapping[str, Mapping[str, Any]] | None = None,
) -> str:
    """The markdown report of a comparison; ``dates`` says when the training data and the
    test days are; ``prediction`` the rows of :func:`scenarios.experiments.prediction.prediction_errors`
    (on a building of several zones, :func:`scenarios.experiments.compare_zones.zone_prediction_errors`,
    with ``zone_rc`` its RC values in place of ``rc``: a section per zone's discomfort besides)."""
    reference = reference_of(rows)
    lines = [
        f"# Closed-loop comparison on `{scenario}`",
        "",
        description,
        "",
        dates,
        "",
        "Every controller ran on the same test days (same weather, prices, comfort band and "
        "perfect forecasts) after the same one-day thermostat warm-up, which is not counted. "
        "KPIs follow BOPTEST: discomfort is the time integral of the comfort-band violation "
        "(1-min resolution), cost is price x delivered energy, the objective is cost + comfort "
        "weight x discomfort, the time ratio is decision time / simulated time. "
        + DISCOMFORT_TEXT + " "
        + _REFERENCE_TEXT.get(reference, f"`/ {reference}` divides each objective by the "
                              f"{reference}'s."),
        "",
        "## KPIs",
        "",
    ]
    columns = kpi_columns(rows)
    headers = ["controller", *(h for _, h, _ in columns)]
    body = [[f"`{r['controller']}`", *_kpi_cells(r, columns)] for r in rows]
    lines += markdown_table(headers, body)
    if zone_rc is not None:
        lines += ["", "## Zones", "", ZONES_TEXT, "", *zone_kpi_table_markdown(rows)]
    if prediction and zone_rc is not None:
        lines += ["", "## Prediction", "", ZONE_PREDICTION_TEXT.format(h=prediction_horizon), "",
                  *zone_prediction_markdown(prediction)]
    elif prediction:
        lines += [
            "",
            "## Prediction",
            "",
            f"Each model predicts the room temperature {prediction_horizon} intervals ahead from "
            "the same starts of held-out data (test part of the weather, the training data's "
            "random policy, not the closed loop): learned models by their own rollout on the "
            "demanded power, RC parameter sets from a Kalman estimate of the state on the "
            "delivered power (see `scenarios.experiments.prediction`). MAE and bias (prediction - truth).",
            "",
            *markdown_table(*_prediction_cells(prediction)),
        ]
    if zone_rc is not None:
        lines += ["", "## RC parameters", "", ZONE_RC_TEXT, "", *zone_rc_table_markdown(zone_rc), ""]
    else:
        lines += [
            "",
            "## RC parameters",
            "",
            "The true building (where the plant has one), the parameters identified from the training data (grey-box, T_m "
            "hidden) and those exported from the trained ensembles (hybrid and PhysNet; geometric "
            "mean over members). Under a heat pump the exports' eta holds the training data's mean "
            "COP; the RC MPCs use the building's own eta and apply the COP per step.",
            "",
            *rc_table_markdown(rc),
            "",
        ]
    lines += [
        "## Trajectories",
        "",
        f"![room temperature and delivered power of every controller]({figure_name})",
        "",
        "## Settings",
        "",
    ]
    lines += markdown_table(["setting", "value"], [[k, f"`{v}`"] for k, v in settings.items()])
    if notes:
        lines += ["", "## Notes", "", *(f"- {n}" for n in notes)]
    return "\n".join(lines) + "\n"


def discomfort_text(kpis: Mapping[str, Any]) -> str:
    """``discomfort 9.92 K h (avoidable 1.51, unavoidable 8.41)`` of a KPI record or fleet
    totals (``unavoidable not computed`` where it was not)."""
    unavoidable = kpis.get("discomfort_unavoidable_kh")
    split = (
        "unavoidable not computed"
        if unavoidable is None
        else f"avoidable {kpis['discomfort_avoidable_kh']:.2f}, unavoidable {unavoidable:.2f}"
    )
    return f"discomfort {kpis['discomfort_kh']:.2f} K h ({split})"


def format_kpis(kpis: RunKpis) -> str:
    """One line: the main KPIs of a run; a building of several zones adds a line per zone."""
    line = (
        f"{kpis['controller']} on {kpis['scenario']}, {kpis['days']} d: "
        f"energy {kpis['energy_kwh']:.2f} kWh, cost {kpis['cost_eur']:.2f} EUR, "
        f"{discomfort_text(kpis)}, peak {kpis['peak_kw']:.2f} kW, "
        f"objective {kpis['objective']:.2f} EUR, decision {kpis['decision_ms_median']:.1f} ms "
        f"(median), overrides {kpis['backup_overrides']}, fallbacks {kpis['fallbacks']}"
    )
    zones = kpis.get("zones") or {}
    if len(zones) < 2:
        return line
    return "\n".join([line, *(
        f"  zone {name}: discomfort {z['discomfort_kh']:.2f} K h (too cold "
        f"{z['discomfort_too_cold_kh']:.2f}, too warm {z['discomfort_too_warm_kh']:.2f}), energy "
        f"{z['energy_kwh']:.2f} kWh"
        for name, z in zones.items()
    )])


def format_fleet(result: FleetResult) -> str:
    """Two lines: a fleet run's totals, and its wall time per control step."""
    info, totals, t = result.info, result.totals, result.step_time
    times = ", ".join(
        f"{part} {t[f'{part}_ms_median']:.1f} ms (p95 {t[f'{part}_ms_p95']:.1f})"
        for part in ("controllers", "plant", "total")
    )
    return (
        f"{info['controller']} x {info['n_buildings']} buildings on {info['scenario']}, "
        f"{info['days']} d: energy {totals['energy_kwh']:.2f} kWh, cost {totals['cost_eur']:.2f} "
        f"EUR, {discomfort_text(totals)}, aggregate peak "
        f"{totals['peak_kw']:.2f} kW, objective {totals['objective']:.2f} EUR, overrides "
        f"{totals['backup_overrides']}, fallbacks {totals['fallbacks']} in "
        f"{totals['buildings_with_fallbacks']} building(s)\n"
        f"time per control step (median): {times}"
    )
