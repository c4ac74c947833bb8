"""Online stage, one module per step of the method: measurement and noise (:mod:`.measurement`;
the files are read by :mod:`podkrig.io.measurement_log`), the measurement check of every door
(units, signs and range against the model: :mod:`.data_check`), misfit (thesis eq. 2.13, :mod:`.misfit`),
the inverse problem (:mod:`.problem`), GA inversion and the FE check (:mod:`.invert`), region of
equivalence and identifiability (:mod:`.region`), response variability (:mod:`.propagation`),
nested analyses (:mod:`.nested`), the Bayesian posterior (:mod:`.posterior`) and the findings
policy — which results deserve a warning, as codes and numbers (:mod:`.findings`; the words are
:mod:`podkrig.reports.findings`).
"""
