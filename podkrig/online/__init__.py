"""Online stage: measurement and noise, misfit (thesis eq. 2.13), GA inversion, region of
equivalence, response variability (RVC), nested analyses and the Bayesian posterior.
"""
