"""Settings of sensor placement: the candidates, the search and the comparison of layouts.

Each field states its default, unit and allowed values once (:mod:`podkrig.config`).
:func:`~podkrig.sensors.placement.place_sensors` takes a :class:`PlacementSettings` (the
:class:`SearchSettings` of the layout, the :class:`ComparisonSettings` of the layouts it is
judged against, the seed); ``podkrig sensors`` builds them, and a :class:`CandidateSettings`, from
its options, whose defaults it shows.

Examples
--------
>>> s = PlacementSettings(search=SearchSettings(k=3, criterion="a"), comparison=ComparisonSettings(n_random=5))
>>> s.search.k, s.search.n_points, s.comparison.n_monte_carlo, s.seed
(3, 64, 0, 0)
>>> CandidateSettings(grid_x="20:380:40", grid_y="20:380:40").lengths
(50.0, 400.0)
"""

import dataclasses
from typing import Annotated

from pydantic import AfterValidator, StrictBool, StrictFloat, StrictInt, StrictStr

from podkrig.config import Seed, allowed, choice, finite, settings, settings_error
from podkrig.sensors.candidates import dic_points, gauge_grid, parse_range, user_candidates
from podkrig.sensors.criteria import CRITERIA, UNIFORM_PRIOR_INFORMATION
from podkrig.sensors.search import METHODS

__all__ = ["CandidateSettings", "ComparisonSettings", "PlacementSettings", "SearchSettings"]

_RANGE_ALLOWED = "START:STOP:STEP in mm, e.g. 45:1125:90"


def _grid_range(text):
    """A grid axis ``"START:STOP:STEP"`` (mm), checked as :func:`parse_range` reads it."""
    try:
        parse_range(text, "")
    except ValueError as e:
        raise settings_error(str(e).split(": ", 1)[-1], allowed=_RANGE_ALLOWED) from None
    return text


_Range = Annotated[StrictStr, AfterValidator(_grid_range), allowed(_RANGE_ALLOWED, unit="mm")]
_Cost = Annotated[StrictFloat, AfterValidator(finite), allowed("a number > 0", gt=0)]
_Length = Annotated[StrictFloat, AfterValidator(finite), allowed("MIN:MAX with 0 < MIN <= MAX, mm", gt=0)]
_Angle = Annotated[StrictFloat, AfterValidator(finite), allowed("finite angles, degrees from x", unit="°")]


def _ordered(lengths):
    if lengths[0] > lengths[1]:
        raise settings_error(f"MIN {lengths[0]:g} > MAX {lengths[1]:g}", allowed="MIN:MAX with 0 < MIN <= MAX, mm")
    return lengths


@settings
class CandidateSettings:
    """Where the candidate sensors come from: a gauge grid (end points on ``grid_x × grid_y``, each
    gauge's length in ``lengths`` and its direction one of ``orientations``), DIC points on
    ``dic_x × dic_y``, and the cost of each kind (a user list of candidates may carry its own)."""

    grid_x: _Range | None = None
    grid_y: _Range | None = None
    lengths: Annotated[tuple[_Length, _Length], AfterValidator(_ordered),
                       allowed("MIN:MAX with 0 < MIN <= MAX, mm", unit="mm")] = (50.0, 400.0)
    orientations: Annotated[tuple[_Angle, ...], allowed("finite angles, degrees from x", unit="°")] = (
        0.0, 45.0, 90.0, 135.0)
    dic_x: _Range | None = None
    dic_y: _Range | None = None
    cost_lvdt: _Cost = 1.0
    cost_dic: _Cost = 1.0

    def __post_init__(self):
        if (self.grid_x is None) != (self.grid_y is None):
            raise settings_error("give both grid_x and grid_y (gauge end-point grid)", "grid_y" if self.grid_x
                                 else "grid_x")
        if (self.dic_x is None) != (self.dic_y is None):
            raise settings_error("give both dic_x and dic_y (DIC point grid)", "dic_y" if self.dic_x else "dic_x")

    def candidates(self, mesh, user=None, forbidden=()):
        """The candidate set on ``mesh``: the gauge grid, the DIC points, then ``user`` definitions
        (``{name: definition}``, the scenario's ``sensors`` format, optional ``cost``; default cost
        ``cost_lvdt``), all outside the ``forbidden`` zones.

        Raises
        ------
        ValueError
            No candidates at all.
        """
        parts = []
        if self.grid_x is not None:
            parts.append(gauge_grid(mesh, parse_range(self.grid_x), parse_range(self.grid_y), lengths=self.lengths,
                                    orientations=self.orientations, forbidden=forbidden, cost=self.cost_lvdt))
        if self.dic_x is not None:
            parts.append(dic_points(mesh, parse_range(self.dic_x), parse_range(self.dic_y), forbidden=forbidden,
                                    cost=self.cost_dic))
        if user is not None:
            parts.append(user_candidates(mesh, user, forbidden=forbidden, cost=self.cost_lvdt))
        if not parts:
            raise ValueError("no candidates: give a gauge grid (--grid-x/--grid-y), DIC points (--dic-x/--dic-y) "
                             "and/or a candidate list (--candidates FILE)")
        candidates = parts[0]
        for extra in parts[1:]:
            candidates = candidates + extra
        return candidates


@settings
class SearchSettings:
    """What the layout minimises and under which constraints: ``k`` sensors or a cost ``budget``
    (exactly one), the ``criterion`` averaged over ``n_points`` Sobol' points of the box, sensors
    always chosen, the smallest spacing, whether the scenario's current sensors are candidates, the
    search starts and the prior information (see :mod:`podkrig.sensors.criteria`)."""

    k: Annotated[StrictInt, allowed("an integer >= 1 (sensors)", ge=1)] | None = None
    budget: Annotated[StrictFloat, AfterValidator(finite), allowed("a number > 0 (total cost)", gt=0)] | None = None
    criterion: choice(CRITERIA) = "d"
    n_points: Annotated[StrictInt, allowed("a power of two >= 1 (Sobol' points of the box)", ge=1)] = 64
    must_include: tuple[StrictStr, ...] = ()
    min_spacing: Annotated[StrictFloat, AfterValidator(finite),
                           allowed("a number >= 0 (between chosen sensor centres)", unit="mm", ge=0)] = 0.0
    include_current: StrictBool = True
    methods: tuple[choice(METHODS), ...] = METHODS
    prior_information: Annotated[StrictFloat, allowed("a number > 0 (1/s0² of the box as a prior, unit "
                                                      "coordinates)", gt=0)] = UNIFORM_PRIOR_INFORMATION


@settings
class ComparisonSettings:
    """How the chosen layout is judged: against ``n_random`` random layouts of its size, and by a
    Monte-Carlo run of the inversion (``n_monte_carlo`` noise realisations at each of ``n_truths``
    interior points; 0: skipped) on a surrogate of ``surrogate_points`` Sobol' points (default
    max(n_points, 128))."""

    n_random: Annotated[StrictInt, allowed("an integer >= 0 (random layouts)", ge=0)] = 20
    n_monte_carlo: Annotated[StrictInt, allowed("an integer >= 0 (noise realisations per truth; 0: skip)", ge=0)] = 0
    n_truths: Annotated[StrictInt, allowed("an integer >= 1 (truth points of the Monte Carlo)", ge=1)] = 1
    surrogate_points: Annotated[StrictInt, allowed("an integer >= 1 (Sobol' points)", ge=1)] | None = None


@settings
class PlacementSettings:
    """A placement job's settings: the search, the comparison and the ``seed`` of the Sobol' set,
    the GA, the random layouts and the Monte Carlo."""

    search: SearchSettings = dataclasses.field(default_factory=SearchSettings)
    comparison: ComparisonSettings = dataclasses.field(default_factory=ComparisonSettings)
    seed: Seed = 0
