"""The defaults that the API, the command line, scenes and the engines share, each written once.

Plain Python, so that the command line's parser shows them without loading
numpy or an engine.
"""

__all__ = ["DF_MAP_SIZE", "HARMONICS", "DF_PERIODS", "SAMPLES_PER_PERIOD", "JUDGE_SAMPLES", "BRANCH_POINTS",
           "K_RANGE", "K_COUNT"]

DF_MAP_SIZE = (16, 48)  # (n_F, n_omega): the DF map on which limit cycles are located
HARMONICS = 10  # the harmonics X_0 .. X_10 a DF point or a cycle records
DF_PERIODS = 150  # periods a DF point may run before it counts as not periodic
SAMPLES_PER_PERIOD = 64  # communication steps per period of a sine sampled into the input (drive "input")
JUDGE_SAMPLES = 512  # co-simulation steps per predicted period when a prediction is judged in closed loop
BRANCH_POINTS = 200  # points per continued branch, at most
K_RANGE = (1e-2, 1e2)  # the gain factors a limit-cycle margin searches
K_COUNT = 25  # the gain factors it scans, log-spaced
