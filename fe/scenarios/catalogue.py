"""What each registered scenario offers: parameters, options, sensors and load levels.

:func:`describe_scenario` builds a scenario with its default options (a mesh and a factorisation
pattern, well under a second) and reports what a user needs to write a spec or a study: every
parameter with unit, default and admissible range; every option with its default; the default
sensors with their definitions; the load levels and their unit. :data:`SENSOR_KINDS` gives the
forms a sensor takes in a spec (TOML), e.g.::

    [sensors]
    D1  = { kind = "gauge", p1 = [302.2, 302.2], p2 = [867.8, 867.8] }
    P   = { kind = "point", point = [585.0, 585.0], component = "y" }
    DIC = { kind = "dic", x0 = 65.0, y0 = 32.5, x1 = 1105.0, y1 = 1072.5, nx = 9, ny = 9 }
"""

import dataclasses
import inspect
import re
from dataclasses import dataclass

from . import SCENARIOS, build_scenario
from .base import ParameterInfo

#: sensor kind → (what it reads, its spec form in TOML)
SENSOR_KINDS = {
    "gauge": (
        "LVDT / extensometer: relative displacement of two points along the line joining them, "
        "mm, positive when they move apart",
        '{ kind = "gauge", p1 = [x1, y1], p2 = [x2, y2] }',
    ),
    "point": (
        "one displacement component of a point (absolute, mm)",
        '{ kind = "point", point = [x, y], component = "x" }   # or "y"',
    ),
    "slip": (
        "relative displacement of two anchors along a fixed direction (default +x), e.g. the slip "
        "of a bed joint read by anchors one above the other, mm",
        '{ kind = "slip", p1 = [x1, y1], p2 = [x2, y2], direction = [1.0, 0.0] }',
    ),
    "dic": (
        "both displacement components on a regular nx × ny grid of points, as digital image "
        "correlation gives them (mm); channels NAME[i,j].ux / .uy",
        '{ kind = "dic", x0 = 0.0, y0 = 0.0, x1 = 100.0, y1 = 100.0, nx = 5, ny = 5 }',
    ),
}


#: typical range of a parameter in tests of clay-brick masonry: (low, high) in the parameter's unit,
#: a starting point for the [parameters] bounds of a study (wider than the values of one wall,
#: narrower than what the model admits). Sources (docs/references.md): the small-assemblage tests
#: summarised by Lourenço (joint strengths, fracture energies, friction, dilatancy), flat-jack
#: practice (Km, sigma0) and the thesis (stiffnesses). These are literature ranges (INFERRED,
#: docs/references.md "INFERRED choices"), not measured values of any one specimen.
TYPICAL_RANGES = {
    "E_b": (5000.0, 16000.0), "nu_b": (0.1, 0.2), "kN_bj": (10.0, 1000.0), "kV_bj": (10.0, 1000.0),
    "r_hj": (0.2, 1.0), "kN_bb": (1e5, 1e6), "kV_bb": (1e5, 1e6),
    "ft_bj": (0.1, 0.9), "c_bj": (0.1, 1.8), "tanphi_bj": (0.6, 1.2), "tanphir_bj": (0.6, 0.9),
    "GfI_bj": (0.005, 0.02), "GfII_bj": (0.01, 0.25), "tanpsi_bj": (0.0, 0.7), "ft_bb": (1.0, 3.0),
    "GfI_bb": (0.05, 0.1), "Km": (0.75, 0.95), "sigma0": (0.1, 0.8),
}


def typical_range(name, unit="-"):
    """``"10–1000 N/mm³"`` for a parameter of :data:`TYPICAL_RANGES`, ``"—"`` for others."""
    if name not in TYPICAL_RANGES:
        return "—"
    lo, hi = (f"{v:.0e}".replace("e+0", "e") if v >= 1e5 else f"{v:g}" for v in TYPICAL_RANGES[name])
    return f"{lo}–{hi}" + ("" if unit in ("-", "") else f" {unit}")


_ROLE = re.compile(r":[\w:.-]+:`(~?)([^`]*)`")


def _role(match):
    tilde, body = match.groups()
    titled = re.fullmatch(r"(.*?)\s*<(.*)>", body, flags=re.S)
    if titled:
        return titled.group(1)
    return body.rsplit(".", 1)[-1] if tilde else body


def plain_text(text):
    """reStructuredText inline markup of a docstring as plain text: ````code```` → ``code``,
    ``:role:`~a.b.c``` → ``c``, ``:role:`title <target>``` → ``title``, ``**bold**`` → ``bold``,
    ```x``` → ``x``.

    >>> plain_text("flat jacks (``flat_jack``), see :func:`~fe.scenarios.build_scenario`")
    'flat jacks (flat_jack), see build_scenario'
    """
    text = _ROLE.sub(_role, text)
    text = re.sub(r"``(.+?)``", r"\1", text)
    text = re.sub(r"\*\*(.+?)\*\*", r"\1", text)
    return re.sub(r"(?<![\w`])`([^`]+)`(?![\w`])", r"\1", text)


@dataclass(frozen=True)
class ScenarioDescription:
    """A scenario's parameters, options, default sensors and load levels.

    Attributes
    ----------
    name : str
    summary : str
        What the test is, one line of plain text (the scenario's ``summary``).
    load_unit : str
    load_levels : tuple of float
        Default load levels, in ``load_unit``.
    parameters : tuple of ParameterInfo
    options : dict
        Option name → default value (lengths mm, loads in ``load_unit``).
    sensors : dict
        Default sensor name → definition dict (mm).
    n_dofs : int
        Degrees of freedom of the default mesh.
    derived : dict
        Values the scenario derived from its options that differ from what was asked, e.g.
        ``support_length_used`` (face → mm) when a rigid support is snapped to element edges.
    constraints : tuple of dict
        Constraints between parameters (:meth:`fe.admissibility.ParameterConstraint.to_dict`:
        ``formula``, ``unit``, ``where``, ``reason``, ``parameters``), checked over a whole
        sampling box before any FE run.
    """

    name: str
    summary: str
    load_unit: str
    load_levels: tuple
    parameters: tuple
    options: dict
    sensors: dict
    n_dofs: int
    derived: dict = dataclasses.field(default_factory=dict)
    constraints: tuple = ()

    def to_dict(self):
        return {
            "name": self.name, "summary": self.summary, "load_unit": self.load_unit,
            "load_levels": list(self.load_levels),
            "parameters": [{**dataclasses.asdict(p), "typical": list(TYPICAL_RANGES[p.name])
                            if p.name in TYPICAL_RANGES else None} for p in self.parameters],
            "options": {k: list(v) if isinstance(v, tuple) else v for k, v in self.options.items()},
            "sensors": self.sensors, "n_dofs": self.n_dofs, "derived": self.derived,
            "constraints": [dict(c) for c in self.constraints],
            "sensor_kinds": {k: {"reads": r, "toml": f} for k, (r, f) in SENSOR_KINDS.items()},
        }

    @classmethod
    def from_dict(cls, d):
        return cls(d["name"], d["summary"], d["load_unit"], tuple(d["load_levels"]),
                   tuple(ParameterInfo(**{k: v for k, v in p.items() if k != "typical"}) for p in d["parameters"]),
                   {k: tuple(v) if isinstance(v, list) else v for k, v in d["options"].items()},
                   dict(d["sensors"]), int(d["n_dofs"]), dict(d.get("derived", {})),
                   tuple(dict(c) for c in d.get("constraints", ())))


def describe_scenario(spec):
    """Describe a registered scenario (a name, a spec dict or a :class:`ScenarioSpec`).

    Raises
    ------
    SpecError
        Unknown scenario or invalid options (the message lists what is allowed).
    """
    scenario = build_scenario(spec)
    cls = SCENARIOS[scenario.name]
    doc = (inspect.getdoc(cls) or cls.__name__).strip()
    summary = plain_text(cls.summary or " ".join(doc.split("\n\n")[0].split()))
    options = {f.name: getattr(scenario.options, f.name) for f in dataclasses.fields(scenario.options)
               if f.name != "sensors"}
    parameters = tuple(dataclasses.replace(p, description=plain_text(p.description))
                       for p in scenario.parameters.values())
    return ScenarioDescription(
        name=scenario.name, summary=summary, load_unit=scenario.load_unit,
        load_levels=tuple(float(v) for v in scenario.load_levels),
        parameters=parameters, options=options,
        sensors=scenario.sensor_definitions(), n_dofs=int(scenario.n_dofs), derived=scenario.derived(),
        constraints=tuple(c.to_dict() for c in scenario.constraints),
    )
