"""A small diagonal-compression lab study (a 2 × 1 panel, 8 training runs) shared by the tests
that feed it good and bad measurement logs; its log is ``log.csv`` beside the study file."""

STUDY = """\
name = "lab"
[scenario]
scenario = "diagonal_compression"
nx = 2
ny = 1
[parameters]
kN_bj = { lower = 30.0, upper = 300.0, scale = "log" }
kV_bj = { lower = 10.0, upper = 120.0, scale = "log" }
E_b = { lower = 8000.0, upper = 14000.0 }
[fixed]
r_hj = 0.6
[sampling]
train = { n = 8, seed = 0 }
held_out = { n = 4, seed = 1, method = "random" }
workers = 1
[measurement]
file = "log.csv"
instrument = "lvdt"
[inversion]
population_size = 8
generations = 2
n_starts = 1
region_samples = 1024
"""
