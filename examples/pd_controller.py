"""A PD controller as a Python FMU slave: the second model that cosim_levitation.py and libcosim_system/ couple.

Needs: pip install pythonfmu (the examples build it with pythonfmu's FmuBuilder; `pythonfmu build -f
pd_controller.py` does the same from a shell).

It reads the ball's height h and velocity v and, between t_on and t_off, outputs the force
F = m g + kp (h_set - h) - kd v that holds the ball at h_set; outside that window F = 0. F depends
on the inputs directly (no delay inside the controller), so a master should set h and v before it
reads F.
"""

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class PDController(Fmi2Slave):
    author = "bouncingball examples"
    description = "PD controller holding a ball at a set height between t_on and t_off"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.h, self.v = 0.0, 0.0  # inputs: the ball's height [m] and velocity [m/s]
        self.kp, self.kd, self.h_set = 40.0, 12.0, 1.0  # N/m, N s/m, m: poles at -6 +- 2i rad/s
        self.m, self.g = 1.0, 9.81  # kg, m/s2: the weight to carry
        self.t_on, self.t_off = 2.25, 5.0  # s
        self.time = 0.0
        for name in ("h", "v"):
            self.register_variable(Real(name, causality=Fmi2Causality.input, variability=Fmi2Variability.continuous))
        for name in ("kp", "kd", "h_set", "m", "g", "t_on", "t_off"):
            self.register_variable(Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed))
        self.register_variable(Real("F", causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                                    getter=self.force))

    def force(self) -> float:
        if not self.t_on <= self.time < self.t_off:
            return 0.0
        return self.m * self.g + self.kp * (self.h_set - self.h) - self.kd * self.v

    def do_step(self, current_time, step_size):
        self.time = current_time + step_size
        return True
