"""``podkrig serve``: a local web front end over a study's output folder or study file.

A page served by podkrig itself (no other host is ever asked for anything: its chart bundle is
vendored in ``static/vendor``) to explore a calibration problem with sliders, run the calibration
stage (:func:`podkrig.online.calibrate.calibrate`) with the parameters frozen on the page, look at
the FE model, and start the study's offline stage in the background. The front end calls the
study and the calibration stage; it orders no step of the method itself.
"""
