# The shipped behaviour is a reference solution.
from bots.behaviours.floor import FollowLine as LineFollower  # noqa: F401
