"""Studies made of many runs: convergence (with its error measures and the dask executor), sweeps, the stress
matrix and the micro/macro comparison."""
