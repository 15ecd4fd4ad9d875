"""The run loop and what it records: the one place that holds both ground truth and what the robots
believe. `loop` steps a run (`run`, `RobotSetup`), `samples` holds what it recorded (`RobotLog`,
`RunResult`), `ending` says how it ended (`Ending`), `clock` limits a controller's step.
"""
