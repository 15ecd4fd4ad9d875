"""Lab exercises with automatic checking (`ctsim lab`).

Exercises are folders of data plus a small checker (`exercise`); a student's file runs in a
sandbox of its own (`sim.sandbox`) with a time limit per scenario (`student`); `checking` runs one
file through an exercise's scenarios and `grading` a whole folder of submissions in parallel.
"""

from sim.lab.checking import CheckReport, check_file, table
from sim.lab.exercise import Exercise, ExerciseError, exercise, exercises

__all__ = ["CheckReport", "Exercise", "ExerciseError", "check_file", "exercise", "exercises", "table"]
