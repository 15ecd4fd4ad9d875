from bots.commands import Twist

BLACK = 0x350


class LineFollower:
    speed = 0.12

    def reset(self, robot):
        self.side = 1.0

    def step(self, t, readings):
        left, right = readings.line[0] > BLACK, readings.line[1] > BLACK
        if left != right:
            self.side = 1.0 if left else -1.0
            return Twist(self.speed, self.side * self.speed * 12.0)
        return Twist(self.speed, 0.0) if left else Twist(0.0, 0.0)
