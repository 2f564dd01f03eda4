"""Safety: the supervisor (rig states, latched faults, the safe pressure) and what
stands beside it in every muscle's tick:

* `plausibility`: is each reading believable (jumps, impossible lengths, frozen or
  zero readings)? A reading that is not is a fault naming the sensor, and the
  signal is no longer trusted by anything downstream.
* `limits`: hard limits (faults) and the soft-limit guards, which act on the valve
  command only in their restoring direction and only on trusted signals.
* `limiter`: the supervisor's invariants, applied last: in a safe state never below
  the safe pressure and never faster than the slew limit; never above the limits.
"""

from pamd.loop.safety.supervisor import Supervisor, Transition, safe_pressure_bar

__all__ = ["Supervisor", "Transition", "safe_pressure_bar"]
