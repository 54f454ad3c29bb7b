"""One comparison with the paper (:class:`Check`), a figure's comparisons (:class:`Section`), and
the small statistics the figures share."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.stats import linregress, spearmanr, t

from pipeline.config.material import FollicleConfig
from pipeline.config.physics import ModelConfig
from pipeline.reports.document import jsonable, number
from pipeline.reports.published import Published


@dataclass(frozen=True)
class Check:
    """A published value beside ours. ``agrees`` is None where no verdict is possible (our value
    is missing, or the published one is a statement we only report beside)."""

    name: str
    label: str
    published: Any
    simulated: Any
    agrees: bool | None
    criterion: str
    published_sd: float | None = None
    also_published: dict | None = None
    source: str = ""
    detail: str = ""          # what stands beside ours (e.g. slope and p of a sign check)

    def ours(self) -> str:
        return number(self.simulated) + (f" ({self.detail})" if self.detail else "")

    def line(self) -> str:
        published = number(self.published)
        if self.published_sd is not None:
            published += f" ± {number(self.published_sd)}"
        return f"{self.label}: published {published}, ours {self.ours()}"

    def as_dict(self) -> dict:
        return jsonable({"name": self.name, "label": self.label, "published": self.published,
                         "published_sd": self.published_sd, "also_published": self.also_published,
                         "simulated": self.simulated, "detail": self.detail, "agrees": self.agrees,
                         "criterion": self.criterion, "source": self.source})


@dataclass
class Section:
    """One table or figure of the paper: its checks, the numbers behind it (``summary``, saved in
    validation.json), the arrays it plots (``series``, not saved) and its caption."""

    name: str
    title: str
    checks: list[Check]
    summary: dict
    series: dict = field(default_factory=dict)
    caption: str = ""

    def full_caption(self) -> str:
        compared = "; ".join(check.line() for check in self.checks)
        return f"{self.caption} Published vs ours — {compared}."


def check(name: str, label: str, published: Published, simulated, agrees, criterion: str, **extra) -> Check:
    """A :class:`Check` of ``published`` (value, sd, source); a missing ``simulated`` has no verdict."""
    missing = simulated is None or (isinstance(simulated, float) and not np.isfinite(simulated))
    return Check(name, label, published.value, simulated, None if missing else agrees, criterion,
                 published_sd=published.sd, source=published.source, **extra)


def linear_fit(x, y) -> dict:
    """Least-squares line y = slope·x + intercept with r², adjusted r², the slope's p-value and se."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    n = len(x)
    if n < 3 or np.ptp(x) == 0:
        return {"slope": float("nan"), "intercept": float("nan"), "r2": float("nan"),
                "adj_r2": float("nan"), "p_value": float("nan"), "slope_se": float("nan"), "n": n}
    fit = linregress(x, y)
    r2 = float(fit.rvalue ** 2)
    return {"slope": float(fit.slope), "intercept": float(fit.intercept), "r2": r2,
            "adj_r2": 1 - (1 - r2) * (n - 1) / (n - 2), "p_value": float(fit.pvalue),
            "slope_se": float(fit.stderr), "n": n}


def slope_difference_p(a: dict, b: dict) -> float:
    """Two-sided p-value that two :func:`linear_fit` slopes are equal (t test, n_a + n_b − 4 dof)."""
    se = np.hypot(a["slope_se"], b["slope_se"])
    dof = a["n"] + b["n"] - 4
    if not (se > 0 and dof > 0):
        return float("nan")
    return float(2 * t.sf(abs(a["slope"] - b["slope"]) / se, dof))


def spearman(x, y) -> float:
    """Rank correlation of finite pairs (NaN with fewer than 3)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    keep = np.isfinite(x) & np.isfinite(y)
    if keep.sum() < 3 or np.ptp(x[keep]) == 0 or np.ptp(y[keep]) == 0:
        return float("nan")
    return float(spearmanr(x[keep], y[keep])[0])


def with_follicle(config: ModelConfig, follicle: FollicleConfig) -> ModelConfig:
    """``config`` with another follicle (the bench protocols clamp the base: rigid); a follicle
    extension of the model is dropped, as it would override the material's follicle."""
    return config.model_copy(update={"material": config.material.model_copy(update={"follicle": follicle}),
                                     "extensions": {k: v for k, v in config.extensions.items() if k != "follicle"}})


def rigid(config: ModelConfig) -> ModelConfig:
    return with_follicle(config, FollicleConfig())


def with_output_rate(config: ModelConfig, rate_hz: float) -> ModelConfig:
    """``config`` sampled at ``rate_hz``, its step shortened to one output period if longer."""
    engine = config.engine.model_copy(update={"output_rate_hz": rate_hz,
                                              "dt_s": min(config.engine.dt_s, 1.0 / rate_hz)})
    return config.model_copy(update={"engine": engine})
