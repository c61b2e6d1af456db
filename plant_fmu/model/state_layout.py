"""Where each quantity sits in the plant's state and input vectors, defined once.

Two state vectors (SI, angles in rad):

* the *state* (``STATE_NAMES``, 14 values): what the FMU outputs, the start values, the
  derivative :meth:`~plant_fmu.model.dynamics.PlantModel.derivative` (attitude as Euler
  angles) and every analysis tool (equilibria, linearisations) use::

      [north, east, down, roll, pitch, yaw, u, v, w, p, q, r, mass_position, mass_velocity]

* the *stepping state* (``STEP_STATE_NAMES``, 18 values): the state followed by the unit
  quaternion [q_w, q_x, q_y, q_z] of the body-to-earth rotation (Hamilton convention,
  scalar first). The two describe one attitude; :mod:`plant_fmu.model.stepping`
  integrates one of them (the *chart*) and refreshes the other after every sub-step: the
  Euler angles while |pitch| <= ``QUATERNION_CHART_PITCH``, the quaternion beyond it (the
  full 6-DOF variant only: no singularity at pitch +-90 deg).

Inputs (``INPUT_NAMES``), held constant over a step::

    [thrust, roll_torque, tunnel_force, fin_angle, mass_position_cmd,
     current_north, current_east, current_down]

The slices and indices below are the only place that spells these positions out.
"""

from __future__ import annotations

STATE_NAMES: tuple[str, ...] = (
    "north", "east", "down", "roll", "pitch", "yaw",
    "u", "v", "w", "p", "q", "r",
    "mass_position", "mass_velocity",
)  # fmt: skip
STATE_UNITS: tuple[str, ...] = (
    "m", "m", "m", "rad", "rad", "rad",
    "m/s", "m/s", "m/s", "rad/s", "rad/s", "rad/s",
    "m", "m/s",
)  # fmt: skip
QUATERNION_NAMES: tuple[str, ...] = ("quat_w", "quat_x", "quat_y", "quat_z")
STEP_STATE_NAMES: tuple[str, ...] = STATE_NAMES + QUATERNION_NAMES
INPUT_NAMES: tuple[str, ...] = (
    "thrust", "roll_torque", "tunnel_force", "fin_angle", "mass_position_cmd",
    "current_north", "current_east", "current_down",
)  # fmt: skip
INPUT_UNITS: tuple[str, ...] = ("N", "N.m", "N", "rad", "m", "m/s", "m/s", "m/s")

STATE_INDEX = {name: i for i, name in enumerate(STATE_NAMES)}
INPUT_INDEX = {name: i for i, name in enumerate(INPUT_NAMES)}
N_STATES = len(STATE_NAMES)
N_STEP_STATES = len(STEP_STATE_NAMES)
N_INPUTS = len(INPUT_NAMES)

# state
POSITION = slice(0, 3)  # north, east, down (earth frame)
EULER = slice(3, 6)  # roll, pitch, yaw
NU = slice(6, 12)  # nu = [u, v, w, p, q, r] (body frame, over ground)
LINEAR_VELOCITY = slice(6, 9)  # [u, v, w]
ANGULAR_VELOCITY = slice(9, 12)  # [p, q, r]
MASS_POSITION = 12  # y_v
MASS_VELOCITY = 13  # y_v'
# A velocity over ground beyond these is no REMUS 100's (top speed ~2.5 m/s): the state has
# left the model's range, in practice an RK4 sub-step too long for a stiff vehicle file
# (a servo of 200 rad/s at 10 ms), which a step refuses before its values turn inf or nan.
MAX_SPEED = 100.0  # m/s, |u|, |v|, |w|
MAX_TURN_RATE = 100.0  # rad/s, |p|, |q|, |r|
# |initial roll, pitch, yaw| the model takes, rad: the plant counts whole turns, but a
# double's spacing grows with its size (1.2e-10 rad at 1e6 rad, 2 rad at 1e16 rad), so far
# beyond a few turns the angle within its turn, all the dynamics see, is lost to rounding.
# 1e6 rad (160,000 turns) keeps it to 1e-10 rad; no heading is meant beyond it.
MAX_START_ANGLE = 1e6
STATE = slice(0, N_STATES)  # the state within the stepping state
QUATERNION = slice(N_STATES, N_STEP_STATES)  # [q_w, q_x, q_y, q_z] in the stepping state
DOWN = 2  # depth, within POSITION
PITCH = 4  # theta, within EULER

# Beyond this |pitch| (rad) the full variant's sub-steps integrate the quaternion, below it
# the Euler angles. Why a switch, not the quaternion everywhere: both are exact, but RK4
# truncates them differently (~1e-6 over a minute of chattering thruster), and below 70 deg
# the Euler angles give every earlier result bit for bit (the built-in scenarios reach 58
# deg); near 90 deg their rates grow as 1/cos(pitch) and stop at the singularity.
QUATERNION_CHART_PITCH = 1.2217304763960306  # 70 deg

# inputs
MASS_COMMAND = 4  # mass_position_cmd
CURRENT = slice(5, 8)  # current_north, current_east, current_down (earth frame)
