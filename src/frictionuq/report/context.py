"""What the sections read from a workflow run folder, loaded once and cached: the ingested
campaign, the fit summary, each fit's record (fit.json) and posterior (posterior.nc), the
campaign's applied-force unit and which paper the run is compared with."""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from .. import units as U
from ..errors import InputError

PUBLISHED = ("brfd", "mfd", "none")


def read_json(path: Path, what: str) -> dict:
    try:
        doc = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as e:
        raise InputError(f"{path}: cannot read {what} ({' '.join(str(e).split())})") from None
    if not isinstance(doc, dict):
        raise InputError(f"{path}: expected a JSON object ({what})")
    return doc


def section_of(doc: dict, key: str) -> dict:
    v = (doc or {}).get(key)
    return v if isinstance(v, dict) else {}


@dataclass
class Context:
    run_dir: Path
    workflow: dict
    provenance: dict
    _cache: dict = field(default_factory=dict)

    def __post_init__(self):
        self.run_dir = Path(self.run_dir)
        self.workflow = self.workflow if isinstance(self.workflow, dict) else {}
        self.provenance = self.provenance if isinstance(self.provenance, dict) else {}

    # ------------------------------------------------------------ folders
    @property
    def fit_dir(self) -> Path:
        return self.run_dir / "fit"

    def _cached(self, key, make):
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    # ------------------------------------------------------------ campaign
    def campaign(self):
        """The ingested campaign (records read), or None when the run has no ingest folder."""
        def make():
            ing = self.run_dir / "ingest"
            if not (ing / "manifest.json").is_file():
                return None
            from ..ingest import load_ingested
            return load_ingested(ing)
        return self._cached("campaign", make)

    def summary(self) -> dict | None:
        def make():
            p = self.fit_dir / "summary.json"
            return read_json(p, "the fit summary") if p.is_file() else None
        return self._cached("summary", make)

    def fits(self) -> list[dict]:
        s = self.summary()
        fits = (s or {}).get("fits")
        return [f for f in fits if isinstance(f, dict) and "id" in f] if isinstance(fits, list) else []

    def applied_unit(self) -> str:
        camp = self.campaign()
        if camp is not None and camp.units.get("applied"):
            return camp.units["applied"]
        u = section_of(self.summary() or {}, "units").get("applied")
        return u if isinstance(u, str) and u in U.UNITS["applied"] else "N"

    def applied_value(self, value_si):
        """An applied level (SI) in the campaign's unit (None stays None)."""
        return None if value_si is None else float(U.from_si(float(value_si), "applied", self.applied_unit()))

    def applied_number(self, value_si) -> str:
        """An applied level (SI) as a number in the campaign's unit, without the unit."""
        return "mixed" if value_si is None else f"{self.applied_value(value_si):g}"

    # ------------------------------------------------------------ fits
    def fit_record(self, fit_id: str) -> dict:
        return self._cached(("fit.json", fit_id),
                            lambda: read_json(self.fit_dir / fit_id / "fit.json", f"the record of fit {fit_id}"))

    def posterior(self, fit_id: str):
        """The fit's ArviZ DataTree (posterior.nc), loaded once."""
        def make():
            from .. import azadapter
            nc = self.fit_dir / fit_id / "posterior.nc"
            if not nc.is_file():
                raise InputError(f"{nc}: missing (posterior of fit {fit_id})")
            return azadapter.load(nc)
        return self._cached(("posterior", fit_id), make)

    # ------------------------------------------------------------ what the workflow asks for
    def disabled(self, stage: str) -> bool:
        """Whether the workflow turns the stage ([compare], [discrepancy]) off. The run folder can
        still hold an earlier run's outputs of it, which the report does not show as this
        workflow's; without a workflow (a bare run folder) nothing is disabled."""
        return section_of(self.workflow, stage).get("enabled") is False

    def predictions(self) -> set[str] | None:
        """Names of the predictions the workflow asks for ("validation" when it validates on
        held-out tests); None without a [predict] table (every prediction folder is shown)."""
        p = section_of(self.workflow, "predict")
        if not p:
            return None
        names = {"validation"} if p.get("validate") else set()
        for key in ("harmonic", "ground_motion"):
            names.update(e.get("name") for e in p.get(key) or [] if isinstance(e, dict))
        return names

    # ------------------------------------------------------------ report options
    def title(self) -> str:
        rep = section_of(self.workflow, "report")
        wf = section_of(self.workflow, "workflow")
        name = wf.get("name") or section_of(self.provenance, "workflow").get("name") or self.run_dir.name
        return str(rep.get("title") or f"frictionuq report: {name}")

    def published(self) -> str:
        """'brfd', 'mfd' or 'none' (workflow [report] published; default none)."""
        v = str(section_of(self.workflow, "report").get("published", "none") or "none").lower()
        return v if v in PUBLISHED else "none"

    def is_brfd(self) -> bool:
        """The device is the BRFD: compared with the BRFD paper, or named so by the campaign."""
        if self.published() == "brfd":
            return True
        camp = self.campaign()
        text = f"{getattr(camp, 'device', '')} {getattr(camp, 'name', '')}".upper() if camp else ""
        return "BRFD" in text
