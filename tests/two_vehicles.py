"""Two vehicles in one scenario: two AuvPlant and two AuvAutopilot instances, each
autopilot closing the loop on its own plant through explicit connections."""

from __future__ import annotations

MEASURED = ("yaw", "r", "p", "roll", "v_rel", "u_rel", "mass_position", "mass_velocity")
COMMANDS = ("mass_position_cmd", "thrust", "tunnel_force")
UNUSED = ("fin_angle",)  # plant inputs left unconnected (lateral plants: no depth)
UNUSED_MEASURED = ("down", "pitch", "q", "w_rel")  # autopilot inputs no law reads here


def pair_connections(plant: str, controller: str) -> list[str]:
    """The ``connections.add`` entries closing ``controller``'s loop on ``plant``."""
    return [f'{{ from = "{plant}.{m}", to = "{controller}.{m}" }}' for m in MEASURED] + [
        f'{{ from = "{controller}.{c}", to = "{plant}.{c}" }}' for c in COMMANDS
    ]


def pair_unused(plant: str, controller: str) -> list[str]:
    """The inputs of the pair no connection drives, quoted for ``connections.remove``."""
    return [f'"{plant}.{u}"' for u in UNUSED] + [f'"{controller}.{u}"' for u in UNUSED_MEASURED]


def two_vehicles_toml(same_names: bool = False, stop_time: float = 10.0) -> str:
    """Vehicle ``a`` (plant_a, ctrl_a: LQR) and ``b`` (plant_b, ctrl_b: backstepping with
    the tunnel thruster), both lateral, from v0 = -0.1 m/s; ``same_names``: the default
    same-name connections on, every ambiguous input named in connections.add or remove."""
    add = pair_connections("plant_a", "ctrl_a") + pair_connections("plant_b", "ctrl_b")
    remove = pair_unused("plant_a", "ctrl_a") + pair_unused("plant_b", "ctrl_b")
    lines = [
        'id = "two-vehicles"',
        f"stop_time = {stop_time!r}",
        "[coupling]",
        "step = 0.01",
        'order = ["ctrl_a", "plant_a", "ctrl_b", "plant_b"]',
        'extrapolation = "none"  # the LQR is designed for its command held',
    ]
    for name, mode in (("a", "lqr"), ("b", "backstepping")):
        lines += [
            f"[instances.plant_{name}]",
            'fmu = "AuvPlant"',
            f"[instances.plant_{name}.start]",
            'variant = "lateral"',
            "u_0 = 1.5",
            "v_0 = -0.1",
            f"[instances.ctrl_{name}]",
            'fmu = "AuvAutopilot"',
            f"[instances.ctrl_{name}.start]",
            f'heading_mode = "{mode}"',
        ]
    lines += ["[connections]", f"same_names = {str(same_names).lower()}"]
    if same_names:
        lines.append(f"remove = [{', '.join(remove)}]")
    lines.append(f"add = [{', '.join(add)}]")
    return "\n".join(lines) + "\n"
