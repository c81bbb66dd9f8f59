"""How much of the measured peak deficit the chapter's 2.5 MHz vibrometers explain
(Fig. 5.2a), from the vibrometer study's table."""
from __future__ import annotations

import math

import pandas as pd

from ... import reductions
from .common import SIM_MATERIAL, PackedChain, make_row, pct

# the chapter's measured peaks (Fig. 5.2c) and its vibrometers' bandwidth
EXP_VMAX_OVER_VS = {"v_max,1": 0.57, "v_max,2": 0.46}
CHAPTER_BANDWIDTH_HZ = 2.5e6


def instrument_rows(pk: PackedChain, vibrometer: pd.DataFrame | None = None) -> list[dict]:
    """Per filter of the vibrometer study, at its bandwidth nearest the chapter's 2.5 MHz:
    the peak loss the instrument causes on the packed 440C chain (1 - recorded/true,
    median over striker speeds) against the chapter's measured deficit (1 - measured /
    this project's packed slope), and the bias it puts on dt. ratio = the fraction of
    the deficit the instrument explains; the reason also says what remains."""
    if vibrometer is None:
        return [make_row(f"vib_{q}", f"{q}: peak loss of the chapter's 2.5 MHz vibrometers",
                         "experiment", "bandwidth 'not expected' to affect peak values",
                         math.nan, math.nan, "fraction", "vibrometer.csv",
                         "vibrometer table not given (the preset has no vibrometer study)")
                for q in ("vmax1", "vmax2")]
    bands = reductions.vibrometer_bands(vibrometer)
    bw = reductions.nearest_bandwidth(vibrometer, CHAPTER_BANDWIDTH_HZ)
    at = bands[bands["bandwidth_hz"].astype(float) == bw]
    deficits = {"v_max,1": 1.0 - EXP_VMAX_OVER_VS["v_max,1"] / pk.s1,
                "v_max,2": 1.0 - EXP_VMAX_OVER_VS["v_max,2"] / pk.s2}
    speeds = sorted(set(vibrometer["v_striker_m_s"].astype(float)))
    vtxt = f"v_s = {speeds[0]:g}-{speeds[-1]:g} m/s"
    rows = []
    for f in sorted(set(at["filter"])):
        packed = at[(at["filter"] == f) & (at["material"] == SIM_MATERIAL)
                    & (at["gap_mean_nm"].astype(float) == 0)]
        gapped = at[(at["filter"] == f) & (at["material"] == SIM_MATERIAL)
                    & (at["gap_mean_nm"].astype(float) > 0)]
        for q, key in (("v1", "v_max,1"), ("v2", "v_max,2")):
            if len(packed):
                p = packed.iloc[0]
                loss, worst = 1.0 - p[f"{q}_median"], 1.0 - p[f"{q}_min"]
                best = 1.0 - p[f"{q}_max"]
            else:
                loss = worst = best = math.nan
            deficit = deficits[key]
            share = loss / deficit if deficit > 0 else math.nan
            gtxt = "; ".join(f"{g:g} nm gaps: median {pct(1.0 - r[f'{q}_median'])}, up to "
                             f"{pct(1.0 - r[f'{q}_min'])}"
                             for g, r in zip(gapped["gap_mean_nm"].astype(float),
                                             (gapped.iloc[i] for i in range(len(gapped)))))
            low = bands[(bands["filter"] == f) & (bands["material"] == SIM_MATERIAL)
                        & (bands["gap_mean_nm"].astype(float) == 0)].sort_values("bandwidth_hz")
            low_txt = (f"even at the study's lowest bandwidth, {low['bandwidth_hz'].iloc[0] / 1e6:g}"
                       f" MHz, the median loss is {pct(1.0 - low[f'{q}_median'].iloc[0])}"
                       if len(low) else "")
            verdict = ("so the bandwidth explains little of it, as the chapter expects"
                       if abs(share) < 0.1 else
                       "so the bandwidth explains a sizeable part of it, against the "
                       "chapter's expectation")
            rows.append(make_row(
                f"vib_{key.replace(',', '').replace('_', '')}_{f}",
                f"{key}: peak loss of a {bw / 1e6:g} MHz {f} vibrometer (order "
                f"{int(vibrometer['order'].iloc[0])}) on the packed 440C chain, 1 - recorded/"
                f"true, median over {vtxt}, against the chapter's measured deficit",
                "experiment", f"bandwidth 'not expected' to affect peaks; measured {key} = "
                f"{EXP_VMAX_OVER_VS[key]} v_s, {pct(deficit)} below this model",
                deficit, loss, "fraction", "fig5_2a; vibrometer; vibrometer.csv",
                f"the instrument lowers {key} by {pct(loss)} (range {pct(best)} to "
                f"{pct(worst)} over {vtxt}; {gtxt or 'no gapped chains'}): it explains "
                f"{pct(share)} of the {pct(deficit)} deficit and leaves "
                f"{pct(deficit - loss)} of v_max unexplained, {verdict}; {low_txt}"))
        if len(packed):
            p = packed.iloc[0]
            rows.append(make_row(
                f"vib_dt_{f}", f"dt (peak to peak, particles 2-13): relative bias of a "
                f"{bw / 1e6:g} MHz {f} vibrometer on the packed 440C chain, median over {vtxt}",
                "experiment", "time delays 'not affected by the bandwidth limit'", 0.0,
                p["dt_median"], "fraction", "vibrometer; vibrometer.csv",
                f"the filter delays both probes alike, so dt moves only with the pulse-shape "
                f"difference between particles 2 and 13: {p['dt_min']:.1e} to "
                f"{p['dt_max']:.1e} of dt; the chapter's slow measured v_g are not an "
                f"instrument effect"))
    return rows
