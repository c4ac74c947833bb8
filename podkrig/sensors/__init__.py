"""Optimal sensor placement (design stage): where to put the gauges so that the identification is
as sharp as the noise allows (thesis ch. 5; Chisari et al., Struct. Multidisc. Optim. 2017).

- :mod:`podkrig.sensors.candidates` — candidate gauges on a grid, DIC points, user lists, zones;
- :mod:`podkrig.sensors.sensitivity` — readings and exact parameter sensitivities of every candidate
  from one FE factorisation per parameter point (affine stiffness);
- :mod:`podkrig.sensors.criteria` — D-, A-, E-optimal and POD criteria over a Sobol' set of the box;
- :mod:`podkrig.sensors.search` — greedy, QR pivoting and GA searches with constraints;
- :mod:`podkrig.sensors.montecarlo` — the actual inversion repeated under noise on a layout;
- :mod:`podkrig.sensors.settings` — the candidates', the search's and the comparison's settings;
- :mod:`podkrig.sensors.placement` — the whole job (:func:`place_sensors`) and its result.
"""
