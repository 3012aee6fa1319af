"""``lts bench``: benchmarks of the rasteriser, of training (run time against error, the ablation
table, the warm-start noise curve), of the calibration and of the images' own ceiling of fidelity,
each printing one JSON object with ``--json``."""
