"""The shipped scenes: one per figure of the paper (fig*.toml) and one per limit-cycle example (lc_*.toml)."""
