"""The column layout of the world's packed tables, read by the compiled kernels
(`sim.world.kernels`) and filled by the World (`sim.world.physics`)."""

from __future__ import annotations

# A kernel call costs tens of nanoseconds per argument, so a world's step passes its per-robot
# values packed into a few 2-D arrays (`sim.world.physics` keeps named views of the columns):
# per-robot parameters (n, PARAMS) float64, fixed once the robots are in
COMMAND_MAX, MAX_SPEED, LAG, MAX_CHANGE, TICKS_PER_RAD = 0, 1, 2, 3, 4
REAL_RADIUS = 5  # left, right wheel (m)
TRACK = 7
MOUNT = 8  # the mouse's x, y in the body frame (m)
COUNTS_PER_METRE, MAX_STEP, SWEEP_RADIUS, APART_RADIUS, MASS, MOMENT, RADIUS = 10, 11, 12, 13, 14, 15, 16
STOPS = 17  # 1: c't-Sim's contact rule (`stop_at_contact`), 0: pymunk's
PARAMS = 18
# per-robot state (n, STATE) float64, two columns (left, right or x, y) each but ALPHA and BLOCKED
WHEEL_SPEED, TICK_CARRY, SLIP, MOUSE_NOISE, MOUSE_CARRY, MOVE, ALPHA = 0, 2, 4, 6, 8, 10, 12
BLOCKED = 13  # 1 when c't-Sim's contact rule refused the step's move
STATE = 14
# per-robot counts (n, TALLIES) int64: encoder ticks (left, right), mouse counts (x, y)
TICKS, COUNTS, TALLIES = 0, 2, 4
# the world's scalars (SCALARS,) float64: floor raster origin (x, y m), cell (m), whether outside
# it is a hole (0/1), the absorption outside it, IR ray length (m), slide margin (m), dt (s), the
# wall grid's origin (x, y m) and cell (m) (`build_wall_grid`), whether robots meet each other (0/1), how far
# the lines stand above the floor (m, `WorldSpec.line_height`)
ORIGIN, CELL, OUTSIDE_IS_HOLE, OUTSIDE_ABSORPTION, IR_LENGTH, SLIDE_MARGIN, DT, WALL_FRAME, ROBOTS_MEET, LINE_HEIGHT = 0, 2, 3, 4, 5, 6, 7, 8, 11, 12
SCALARS = 13
# the wall grid's cells (int64, one array): columns, rows, then the cells' starts (rows x columns
# + 1, row-major; cell k lists members[starts[k]:starts[k + 1]]), the members, a buffer
COLUMNS, ROWS, STARTS = 0, 1, 2
# sensors of all robots (m, SENSOR) float64, floor then light then IR sensors: mount x, y (m),
# height (m; floor, light), view direction (rad; light, IR), half opening or cone (rad; light,
# IR), reach (m; light); and (m, INDEX) int64: owning robot, noise row and curve (IR)
AT, HEIGHT, DIRECTION, OPENING, REACH, PICK, SENSOR = 0, 2, 3, 4, 5, 6, 7  # PICK: 1 for an IR sensor's 'pick' view
OWNER, NOISE_ROW, CURVE, INDEX = 0, 1, 2, 3
GHOST = -2
"""The owner of a robot's circle that no sensor sees (a world of robots that do not meet, `sense_ir`)."""
# the world's count of quiet steps (2,) int64: steps in a row that began with no robot touching a
# wall, and how many such steps pymunk still takes (-1: every step is pymunk's)
STREAK, QUIET_AFTER = 0, 1
