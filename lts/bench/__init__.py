"""``lts bench``: benchmarks of the rasteriser and of training (run time against error, the ablation
table, the warm-start noise curve), each printing one JSON object with ``--json``."""
