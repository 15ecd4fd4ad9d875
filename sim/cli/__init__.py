"""The `ctsim` command line, thin over everything: one module per command (`run`, `view`, `play`,
`report`, `worlds`, `check`, `bridge`, `sweep`, `controllers`, `lab`, `contest`), each adding its
options (`add_parser`) and handling them (`cmd_<command>`); what they share: `options` (exit
statuses, option types, robots), `output` (a run's folder) and `observers` (signals, progress);
`entry.main` parses and dispatches."""
