"""A run seen without installing a viewer: rerun's web viewer served to a browser (`ctsim view`,
`ctsim run --web`) and self-contained HTML reports of runs and sweeps."""
