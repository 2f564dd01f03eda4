"""pamd.sim: the simulated rig, and how the simulation code fits together.

Three places hold simulation code, in this order of layers:

- **`pamd.sim`** (this package): the physics and nothing else. It knows no driver,
  no loop and no protocol, so the simulated driver and the emulator share it.

  - `options`: the sim driver's option dataclasses (per rig and per muscle), with
    their bounds, documentation and the scripted `faults` schedule.
  - `specimen`: what a simulated muscle is by its type (`pamd.muscle_type`: a
    DMSP-20's or DMSP-40's datasheet map, or a custom muscle's table), its inner
    diameter and its hard stops; `bind_types` gives each simulated muscle the type of
    the rig muscle reading its channels.
  - `plant`: one muscle with its hanging load: the static force map, Dahl friction
    whose level follows the braid's normal load (pressure and the muscle's pull) with
    Stribeck stiction, slow force drift, and its sensors.
  - `regulator` (lag pneumatics: the setpoint through a dead time and a lag) or
    `vppm` + `pneumatics` (flow pneumatics: a proportional regulator as a device
    feeding a chamber through ISO 6358 orifices from a shared supply line); `pilot`
    is the regulator's own pressure loop, shared by both.
  - `onoff`: inflate and exhaust solenoid valves (on/off actuation).
  - `model_plant`: a muscle whose mechanics are an identified model's (the `plant_model`
    option: an FN-QUPI file, seed 003's plant for its tracking tables), same regulator
    and sensors; the sim driver loads the file (`pamd.models.fn_qupi_plant`).
  - `sensors`: devices that sample at their own period, with latency, quantisation,
    noise and a filter; the driver stamps each reading with its sample's time.

- **`pamd.drivers.sim`** (`drivers/sim.py`): the `sim` driver, a driver like any
  other behind the `Driver` protocol and the `pamd.drivers` entry points. The loop
  advances it one period per tick (`steps_with_loop`), on the virtual clock or the
  wall clock; it owns the plants and exposes their sensors and valves as channels.

- **`pamd.emulate`**: the same plants served through real field-bus protocols
  (Modbus TCP/RTU, CANopen) from a separate process (`pamd emulate`), so that the
  real drivers (`modbus`, `serial-line`, `canopen-encoder`) run end to end on this
  machine. It steps a `SimDriver` on the wall clock (`emulate.physics`) and maps
  its channels to registers, coils and objects.
"""
