"""What a fit minimises: residual vectors of a model against a measurement.

Every objective has ``residuals(spec)`` (the vector a least-squares optimiser sees),
``error(residuals)`` (the number reported) and ``metric`` (its name):

- :class:`TrajectoryObjective`: tracked positions, simulated − measured over every tracked
  point, frame and axis (in units of 0.1 mm); error = RMS in metres.
- :class:`FeatureObjective`: the paper's features of each trial's tip signal (eq. 4a for
  motor-driven trials, 4b for releases), residuals ln(sim/exp); error = MSA.
- :class:`TableObjective`: resonance tables; each whisker is run through the resonance
  protocol (docs/model.md §5) and f1, the paper's two-peak δ (or, for ``damping=modal`` tables, the
  first in-plane mode's damping ratio ζ1 of the linear chain) and f2, f3 (the linear model's
  in-plane modes) are compared, residuals ln(sim/exp); error = MSA. Where the protocol runs is
  its one hook, :meth:`TableObjective.resonance` (the trial simulator given; the engine's own
  resonance protocol in :mod:`.material_fit`).
"""

from __future__ import annotations

import numpy as np

from pipeline.diagnosis.fastsim import FastSimulator, PreparedTrial
from pipeline.diagnosis.features import (TipSignal, decrement, dominant_side, features, is_release, msa,
                                         smoothing_window)
from pipeline.diagnosis.parameters import ModelSpec
from pipeline.engines.linear.chain import linearise
from pipeline.engines.linear.modal import damped_modes
from pipeline.measurements.table import ResonanceTable
from pipeline.measurements.timeseries import RotationDrive, TimeSeriesMeasurement, Trial
from pipeline.signals.resonance import DURATION_S, analyse_tip, pulse_drive

RESIDUAL_UNIT_M = 1e-4
MISSING_FEATURE_PENALTY = np.log(10.0)     # a feature the simulation does not produce at all


class TrajectoryObjective:
    metric = "rms_m"
    loss = "linear"

    def __init__(self, measurement: TimeSeriesMeasurement, simulator=None):
        self.measurement = measurement
        self.simulator = simulator or FastSimulator()
        self.prepared = [PreparedTrial(t, measurement.gravity_direction) for t in measurement.trials]
        self.masks = [np.isfinite(t.positions_m) for t in measurement.trials]
        self.measured = np.concatenate([t.positions_m[m] for t, m in zip(measurement.trials, self.masks)])

    def simulate(self, spec: ModelSpec) -> list[np.ndarray]:
        return self.simulator.simulate(spec.physics(self.measurement.geometry), self.prepared)

    def blocks(self, duration_s: float) -> np.ndarray:
        """A label per residual: its trial and which ``duration_s`` stretch of it (s) it is in."""
        labels = []
        for index, (trial, mask) in enumerate(zip(self.measurement.trials, self.masks)):
            stretch = ((trial.time_s - trial.time_s[0]) // duration_s).astype(int)
            labels.append((index * 100_000 + np.broadcast_to(stretch[:, None, None], mask.shape))[mask])
        return np.concatenate(labels)

    def residuals_of(self, simulated: list[np.ndarray]) -> np.ndarray:
        sim = np.concatenate([s[m] for s, m in zip(simulated, self.masks)])
        return (sim - self.measured) / RESIDUAL_UNIT_M

    def residuals(self, spec: ModelSpec) -> np.ndarray:
        return self.residuals_of(self.simulate(spec))

    def error(self, residuals: np.ndarray) -> float:
        return float(np.sqrt(np.mean(residuals ** 2)) * RESIDUAL_UNIT_M)


# MSA takes a median: a robust loss on the log-ratios (≈ |r| beyond 2 %) follows it better than
# squares, which let one noisy peak ratio pull the precise frequencies off.
ROBUST_LOSS = ("soft_l1", 0.02)


class FeatureObjective:
    loss = ROBUST_LOSS

    def __init__(self, measurement: TimeSeriesMeasurement, simulator=None):
        self.measurement = measurement
        self.simulator = simulator or FastSimulator()
        self.prepared = [PreparedTrial(t, measurement.gravity_direction) for t in measurement.trials]
        self.signals, self.sides, self.windows, self.measured = [], [], [], []
        for trial in measurement.trials:
            signal = TipSignal(trial, trial.positions_m)
            ringing = signal(trial.positions_m)
            side, window = dominant_side(ringing), smoothing_window(ringing, trial.sampling_rate_hz)
            self.signals.append(signal)
            self.sides.append(side)
            self.windows.append(window)
            self.measured.append(features(ringing, trial.sampling_rate_hz, side, window, is_release(trial)))
        kinds = sorted({"4b" if is_release(t) else "4a" for t in measurement.trials})
        self.metric = "msa_eq" + "+".join(kinds)

    def trial_features(self, simulated: list[np.ndarray]) -> list[dict[str, float]]:
        return [features(signal(sim), trial.sampling_rate_hz, side, window, is_release(trial))
                for signal, sim, side, window, trial in zip(self.signals, simulated, self.sides,
                                                            self.windows, self.measurement.trials)]

    def residuals(self, spec: ModelSpec) -> np.ndarray:
        simulated = self.simulator.simulate(spec.physics(self.measurement.geometry), self.prepared)
        out = []
        for sim, meas in zip(self.trial_features(simulated), self.measured):
            for key, value in meas.items():
                if np.isfinite(value) and value > 0:
                    ratio = sim[key] / value
                    out.append(np.log(ratio) if np.isfinite(ratio) and ratio > 0 else MISSING_FEATURE_PENALTY)
        return np.array(out)

    def error(self, residuals: np.ndarray) -> float:
        return msa(residuals)

    def ratios(self, spec: ModelSpec) -> tuple[float, float]:
        """Median measured/simulated ratios of (FRF, δ) at ``spec`` (δ from y0/y1 for releases)."""
        simulated = self.simulator.simulate(spec.physics(self.measurement.geometry), self.prepared)
        return _median_ratios([(m, s) for m, s in zip(self.measured, self.trial_features(simulated))])


def _median_ratios(pairs) -> tuple[float, float]:
    with np.errstate(divide="ignore", invalid="ignore"):
        freq = np.array([m["frf_hz"] for m, _ in pairs]) / np.array([s["frf_hz"] for _, s in pairs])
        dec = np.array([decrement(m) for m, _ in pairs]) / np.array([decrement(s) for _, s in pairs])
    freq, dec = freq[np.isfinite(freq) & (freq > 0)], dec[np.isfinite(dec) & (dec > 0)]
    return (float(np.median(freq)) if freq.size else 1.0, float(np.median(dec)) if dec.size else 1.0)


def protocol_trial(name: str) -> Trial:
    """The resonance protocol (docs/model.md §5) as a trial: tip of a base pulse about z, 1 s at 1 kHz."""
    drive = pulse_drive()
    angles = np.zeros((len(drive.time_s), 3))
    angles[:, 0] = drive.angle_rad
    time_s = np.arange(0.0, DURATION_S + 5e-4, 1e-3)
    return Trial(name, time_s, np.array([1.0]), np.zeros((len(time_s), 1, 3)),
                 RotationDrive(drive.time_s, angles), 1000.0)


class TableObjective:
    metric = "msa_eq4a"
    loss = "linear"

    def __init__(self, table: ResonanceTable, simulator=None):
        self.table = table
        self.simulator = simulator or FastSimulator()
        self.prepared = [PreparedTrial(protocol_trial(r.whisker), (0.0, 0.0, -1.0)) for r in table.records]

    def record_features(self, spec: ModelSpec) -> list[dict[str, float]]:
        """Simulated f1, δ, ζ1, f2, f3 of every whisker. Records measured on the resonance
        protocol (two-peak δ) run it, f1 and δ from its tip; for modal records (a bandwidth or
        free-decay measurement of the first mode) f1 and ζ1 are the linear chain's first damped
        in-plane mode, as are f2 and f3 for every record."""
        out = []
        for record, prepared in zip(self.table.records, self.prepared):
            physics = spec.physics(record.geometry)
            freqs, zetas, in_plane = damped_modes(linearise(physics))
            modes = freqs[in_plane]
            features = {"f1_hz": modes[0] if len(modes) else np.nan, "log_decrement": np.nan,
                        "zeta1": zetas[in_plane][0] if in_plane.any() else np.nan,
                        "f2_hz": modes[1] if len(modes) > 1 else np.nan,
                        "f3_hz": modes[2] if len(modes) > 2 else np.nan}
            if record.damping_measure != "modal":
                result = self.resonance(spec, record, physics, prepared)
                features.update(f1_hz=result.f1_hz, log_decrement=result.paper_log_decrement)
            out.append(features)
        return out

    def resonance(self, spec: ModelSpec, record, physics, prepared: PreparedTrial):
        """The forward model of a protocol record: the resonance protocol on ``record``'s whisker
        (``physics``, the whisker of ``spec``), here the trial simulator's tip analysed
        (:class:`~pipeline.signals.resonance.ResonanceResult`); a subclass may run it elsewhere."""
        trial = prepared.trial
        positions = self.simulator.simulate(physics, [prepared])[0]
        return analyse_tip(positions[1:, 0, 1], trial.time_s[1:], trial.sampling_rate_hz)

    def measured(self) -> list[dict[str, tuple[float, float]]]:
        """Per whisker: feature → (value, standard deviation) for the measured features."""
        out = []
        for r in self.table.records:
            items = {f"f{m + 1}_hz": (r.frequencies_hz[m], r.frequency_sd_hz[m]) for m in range(3)}
            if r.damping_measure == "modal":
                items["zeta1"] = (r.damping_ratio, r.damping_ratio_sd)
            else:
                items["log_decrement"] = (r.decrement, r.decrement_sd)
            out.append({k: v for k, v in items.items() if np.isfinite(v[0])})
        return out

    def residuals(self, spec: ModelSpec) -> np.ndarray:
        out = []
        for sim, meas in zip(self.record_features(spec), self.measured()):
            for key, (value, _) in meas.items():
                ratio = sim[key] / value
                out.append(np.log(ratio) if np.isfinite(ratio) and ratio > 0 else MISSING_FEATURE_PENALTY)
        return np.array(out)

    def ratios(self, spec: ModelSpec) -> tuple[float, float]:
        """Median measured/simulated ratios of (f1, damping) at ``spec``; damping is δ or ζ1,
        whichever the record measured (both roughly proportional to θ_ζ)."""
        pairs = []
        for m, s in zip(self.measured(), self.record_features(spec)):
            key = "zeta1" if "zeta1" in m else "log_decrement"
            pairs.append(({"frf_hz": m["f1_hz"][0], "log_decrement": m.get(key, (np.nan,))[0]},
                          {"frf_hz": s["f1_hz"], "log_decrement": s[key]}))
        return _median_ratios(pairs)

    def damping_mask(self) -> np.ndarray:
        """True for each residual of a damping (δ or ζ1), False for a frequency."""
        return np.array([key in ("log_decrement", "zeta1") for meas in self.measured() for key in meas])

    def log_sd(self) -> np.ndarray:
        """Standard deviation of each residual's measured value, in log units (NaN unknown)."""
        return np.array([sd / value for meas in self.measured() for value, sd in meas.values()])

    def error(self, residuals: np.ndarray) -> float:
        return msa(residuals)
