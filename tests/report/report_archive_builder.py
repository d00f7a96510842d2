"""Synthetic archives written with h5py exactly as docs/archive.md lays them out (tests and benchmark).

Each configuration's brace loop is an ellipse: angle = m + a sin(wt), brace torque = s (angle - 20) +
b cos(wt). Its area is pi a b deg*N*m, so the energy per cycle (Eq 10-12) is pi^2 a b / 180 J; `b` is
chosen from the energy wanted. Settings follow Appendix A, Table 5, stored as declared factors
(docs/archive.md "Configurations").
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

# key: (run, set, condition, profile, brace_rom, robot_rom, friction, stiffness, speed, preload)
_ROWS = [
    (1, 5, "brace_rom", "Range of motion of the brace", "sinusoid", "R1", "Rr3", "2", "K2", "full", "center"),
    (2, 6, "brace_rom", "Range of motion of the brace", "sinusoid", "R2", "Rr3", "2", "K2", "full", "center"),
    (3, 7, "brace_rom", "Range of motion of the brace", "sinusoid", "R3", "Rr3", "2", "K2", "full", "center"),
    (4, 8, "friction", "Friction", "sinusoid", "R3", "Rr3", "0", "K2", "full", "center"),
    (5, 9, "friction", "Friction", "sinusoid", "R3", "Rr3", "1", "K2", "full", "center"),
    (6, 10, "friction", "Friction", "sinusoid", "R3", "Rr3", "2", "K2", "full", "center"),
    (7, 11, "friction", "Friction", "sinusoid", "R3", "Rr3", "3", "K2", "full", "center"),
    (8, 3, "preload", "Spring pre-load", "sinusoid", "R3", "Rr3", "2", "K2", "full", "first"),
    (9, 4, "preload", "Spring pre-load", "sinusoid", "R3", "Rr3", "2", "K2", "full", "last"),
    (10, 1, "speed", "Speed", "sinusoid", "R3", "Rr3", "2", "K2", "full", "center"),
    (11, 2, "speed", "Speed", "sinusoid", "R3", "Rr3", "2", "K2", "half", "center"),
    (12, 18, "rom_k2", "ROM with medium spring", "sinusoid", "R1", "Rr1", "2", "K2", "full", "center"),
    (13, 19, "rom_k2", "ROM with medium spring", "sinusoid", "R2", "Rr2", "2", "K2", "full", "center"),
    (14, 20, "rom_k2", "ROM with medium spring", "sinusoid", "R3", "Rr3", "2", "K2", "full", "center"),
    (15, 12, "rom_k0", "ROM with no springs", "sinusoid", "R1", "Rr1", "2", "K0", "full", "center"),
    (16, 13, "rom_k0", "ROM with no springs", "sinusoid", "R2", "Rr2", "2", "K0", "full", "center"),
    (17, 14, "rom_k0", "ROM with no springs", "sinusoid", "R3", "Rr3", "2", "K0", "full", "center"),
    (18, 15, "rom_k1", "ROM with small spring", "sinusoid", "R1", "Rr1", "2", "K1", "full", "center"),
    (19, 16, "rom_k1", "ROM with small spring", "sinusoid", "R2", "Rr2", "2", "K1", "full", "center"),
    (20, 17, "rom_k1", "ROM with small spring", "sinusoid", "R3", "Rr3", "2", "K1", "full", "center"),
    (21, 21, "rom_k3", "ROM with largest spring", "sinusoid", "R1", "Rr1", "2", "K3", "full", "center"),
    (22, 22, "rom_k3", "ROM with largest spring", "sinusoid", "R2", "Rr2", "2", "K3", "full", "center"),
    (23, 23, "rom_k3", "ROM with largest spring", "sinusoid", "R3", "Rr3", "2", "K3", "full", "center"),
    (24, 24, "emu", "Direct comparison", "human", "RE", "RrE", "EMU", "K2", "full", "first"),
    (25, 25, "emu", "Direct comparison", "human", "RE", "RrE", "EMU", "K2", "full", "first"),
    (26, 26, "emu", "Direct comparison", "human", "RE", "RrE", "EMU", "K2", "full", "first"),
    (27, 27, "emu", "Direct comparison", "sinusoid", "RE", "RrE", "EMU", "K2", "full", "first"),
    (28, 28, "emu", "Direct comparison", "sinusoid", "RE", "RrE", "EMU", "K2", "half", "first"),
]
TABLE5: dict[int, tuple[Any, ...]] = {row[0]: row[1:] for row in _ROWS}

ROM_DEG = {"R1": (40.0, 90.0), "R2": (20.0, 110.0), "R3": (0.0, 130.0), "RE": (0.0, 110.0)}
ROBOT_ROM_DEG = {"Rr1": (40.0, 90.0), "Rr2": (20.0, 110.0), "Rr3": (0.0, 130.0), "RrE": (0.0, 110.0)}
FRICTION_NM = {"0": 0.0, "1": 1.25, "2": 3.75, "3": 6.25, "EMU": 3.75}
SCREW_TURNS = {"0": 0.0, "1": 0.25, "2": 0.75, "3": 1.25, "EMU": 0.75}
STIFFNESS_N_PER_MM = {"K0": 0.0, "K1": 4.4, "K2": 13.0, "K3": 20.0}
PRELOAD_INDEX = {"first": 1, "center": 3, "last": 5}
SPEED_DEG_S = {"full": 50.0, "half": 25.0}

#: The knee's declared factors, in declaration order (the test copy of a protocol's `factors:`).
FACTORS = ("brace_rom", "robot_rom", "friction", "stiffness", "speed", "preload")

# name -> (parameter, section, title, keys), as a protocol's report section declares them
THESIS_COMPARISONS = {
    "speed": ("speed", "5.1", "Speed", (10, 11)),
    "brace_rom": ("brace_rom", "5.2", "Brace range of motion", (1, 2, 3)),
    "friction": ("friction", "5.3", "Friction", (4, 5, 6, 7)),
    "stiffness": ("stiffness", "5.4", "Stiffness", (17, 20, 14, 23)),
    "preload": ("preload", "5.5", "Preload", (8, 3, 9)),
    "robot_rom": ("robot_rom", "5.7.2", "Trajectory range of motion", (12, 13, 14)),
}


@dataclass
class ConfigSpec:
    """What to synthesise for one configuration."""

    key: int
    energy_j: float = 1.0
    slope_nm_per_deg: float = 0.3
    angle_range_deg: tuple[float, float] | None = None  # the angle reached (default: the robot ROM)
    n_trials: int = 2
    status: str = "complete"
    energy_spread: float = 0.02


@dataclass
class ArchiveSpec:
    """A whole synthetic archive."""

    configs: list[ConfigSpec]
    duration_s: float = 20.0
    rate_hz: float = 1000.0
    status: str = "complete"
    mode: str = "dry-run"
    seed: int = 7
    comparisons: bool = True
    reference: bool = False
    calibration_fail_set: str | None = None
    interrupted: bool = False
    extra_root_attrs: dict[str, object] = field(default_factory=dict)
    # more /comparisons groups: name -> (parameter, section, title, keys), written even without data
    extra_comparisons: dict[str, tuple[str, str, str, tuple[int, ...]]] = field(default_factory=dict)
    # store like archive/h5util.py: large float datasets gzip+shuffle, measured/processed signals float32
    compress_floats: bool = False
    # the archived protocol text (/protocol); its `expectations:` drive the report's verdicts
    protocol_text: str = "name: knee_synthetic\njoint: knee_flexion\n"


_COMPRESS_FLOATS = False
_SIGNALS = {"angle_deg", "torque_nm", "brace_torque_nm", "command_volts"}


def _ds(group: h5py.Group, name: str, data: np.ndarray, units: str, *, gzip: bool = False) -> h5py.Dataset:
    compress = gzip or (_COMPRESS_FLOATS and np.asarray(data).size > 256)
    if _COMPRESS_FLOATS and name in _SIGNALS:
        data = np.asarray(data, dtype=np.float32)
    ds = group.create_dataset(
        name, data=data, compression="gzip" if compress else None, shuffle=compress and not gzip
    )
    ds.attrs["units"] = units
    return ds


def factor_settings(key: int) -> dict[str, dict[str, object]]:
    """Configuration `key`'s settings as the plan's `settings` (docs/archive.md `settings_json`)."""
    _, _, _, _, brace_rom, robot_rom, friction, stiffness, speed, preload = TABLE5[key]
    return {
        "brace_rom": {"level": brace_rom, "range_deg": list(ROM_DEG[brace_rom])},
        "robot_rom": {"level": robot_rom, "range_deg": list(ROBOT_ROM_DEG[robot_rom])},
        "friction": {
            "level": friction,
            "friction_nm": FRICTION_NM[friction],
            "screw_turns": SCREW_TURNS[friction],
        },
        "stiffness": {"level": stiffness, "stiffness_n_per_mm": STIFFNESS_N_PER_MM[stiffness]},
        "speed": {"level": speed, "speed_deg_s": SPEED_DEG_S[speed]},
        "preload": {"level": preload, "preload_index": float(PRELOAD_INDEX[preload])},
    }


def device_of(key: int) -> list[dict[str, object]]:
    """Configuration `key`'s resolved device (docs/archive.md `device_json`)."""
    f = factor_settings(key)
    return [
        {"name": "stops", "type": "rom_stops", "range_deg": f["brace_rom"]["range_deg"], "slack_deg": 13.0},
        {
            "name": "brake",
            "type": "coulomb_brake",
            "torque_nm": f["friction"]["friction_nm"],
            "transition_deg": 2.0,
        },
        {
            "name": "springs",
            "type": "lever_spring",
            "stiffness_n_per_mm": f["stiffness"]["stiffness_n_per_mm"],
            "preload_index": f["preload"]["preload_index"],
            "count": 2.0,
        },
    ]


def settings_of(key: int) -> dict[str, object]:
    """The configuration group's attributes of docs/archive.md ("Configurations"): identity, `factors`,
    `settings_json`, `device_json`, and each factor flattened (`<factor>`, `<factor>.<quantity>`)."""
    run, set_name, condition, profile, *_ = TABLE5[key]
    settings = factor_settings(key)
    out: dict[str, object] = {
        "run": run,
        "set": set_name,
        "condition": condition,
        "profile": profile,
        "trajectory_name": "sine" if profile == "sinusoid" else f"subject_{key}",
        "factors": list(FACTORS),
        "settings_json": json.dumps(settings),
        "device_json": json.dumps(device_of(key)),
    }
    for factor, entry in settings.items():
        out[factor] = entry["level"]
        for quantity, value in entry.items():
            if quantity != "level":
                out[f"{factor}.{quantity}"] = (
                    np.asarray(value, dtype=float) if isinstance(value, list) else float(value)
                )
    return out


def ellipse_b_for_energy(energy_j: float, amplitude_deg: float) -> float:
    """Torque semi-axis b (N*m) giving `energy_j` per cycle: E = pi a b * pi / 180 (Eq 10-12)."""
    return energy_j * 180.0 / (math.pi**2 * amplitude_deg)


def write_archive(path: Path, spec: ArchiveSpec) -> Path:
    """Write `spec` as an archive at `path` following docs/archive.md; return `path`."""
    global _COMPRESS_FLOATS
    _COMPRESS_FLOATS = spec.compress_floats
    rng = np.random.default_rng(spec.seed)
    n = round(spec.duration_s * spec.rate_hz)
    time_s = np.arange(n) / spec.rate_hz
    n_cmd = round(spec.duration_s * 100.0)
    cmd_time = np.arange(n_cmd) / 100.0
    with h5py.File(path, "w") as f:
        f.attrs["protocol_name"] = "knee_synthetic"
        f.attrs["protocol_sha256"] = "ab" * 32
        f.attrs["schema_version"] = 1
        f.attrs["software_version"] = "0.1.0"
        f.attrs["mode"] = spec.mode
        f.attrs["seed"] = spec.seed
        f.attrs["created_utc"] = "2026-11-21T10:15:00Z"
        f.attrs["finished_utc"] = "2026-11-21T10:16:00Z"
        f.attrs["status"] = spec.status
        f.attrs["joint"] = "knee_flexion"
        f.attrs["only"] = np.asarray([c.key for c in spec.configs], dtype=np.int64)
        for k, v in spec.extra_root_attrs.items():
            f.attrs[k] = v
        f.create_dataset("protocol", data=spec.protocol_text).attrs["filename"] = "knee_synthetic.yaml"
        f.create_dataset("plan", data=json.dumps({"protocol": "knee_synthetic", "steps": []}))
        events = [{"t_utc": "2026-11-21T10:15:00Z", "kind": "started", "detail": "dry run"}]
        if spec.interrupted:
            events.append({"t_utc": "2026-11-21T10:15:20Z", "kind": "interrupted", "detail": "SIGINT"})
            events.append({"t_utc": "2026-11-21T10:15:30Z", "kind": "resumed", "detail": "3 units skipped"})
        if spec.status == "complete":
            events.append({"t_utc": "2026-11-21T10:16:00Z", "kind": "finished", "detail": ""})
        sess = f.create_group("session")
        sess.create_dataset("events", data=[json.dumps(e) for e in events], dtype=h5py.string_dtype())
        cl = sess.create_group("checklists").create_group("brace_rom__fit_brace")
        cl.attrs["step_id"] = "brace_rom:fit_brace"
        cl.attrs["title"] = "Fit the brace <R1> & check bolts"
        cl.attrs["items"] = json.dumps(["Set the stops to 40-90 deg", "Tighten the 8 mm bolt to 11 ft-lb"])
        cl.attrs["answer"] = "done"
        cl.attrs["answered_utc"] = "2026-11-21T10:15:01Z"
        cl.attrs["automatic"] = True

        sets = sorted({str(TABLE5[c.key][1]) for c in spec.configs})
        cal = f.create_group("calibration")
        for set_name in sets:
            for when in ("before", "after"):
                g = cal.create_group(f"{set_name}/{when}")
                t = np.arange(3000) / 1000.0
                ct = np.arange(300) / 100.0
                cmd = np.where(ct >= 0.5, 45.0, 0.0)
                ang = np.where(t >= 0.5, 45.0 * (1.0 - np.exp(-(t - 0.5) / 0.2)), 0.0)
                _ds(g, "time_s", t, "s")
                _ds(g, "command_time_s", ct, "s")
                _ds(g, "command_deg", cmd, "deg")
                _ds(g, "angle_deg", ang, "deg")
                _ds(g, "torque_nm", 5.0 * np.sin(t), "N*m")
                _ds(g, "angle_codes", (ang * 10).astype(np.int16), "counts", gzip=True)
                _ds(g, "torque_codes", np.zeros(t.size, np.int16), "counts", gzip=True)
                fail = spec.calibration_fail_set == set_name and when == "after"
                g.attrs["step_id"] = f"{set_name}:calibration:{when}"
                g.attrs["verdict"] = "fail" if fail else "pass"
                g.attrs["step_deg"] = 45.0
                g.attrs["settle_error_deg"] = 3.5 if fail else 0.4
                g.attrs["time_constant_s"] = 0.2
                g.attrs["limits"] = json.dumps({"settle_error_deg": 2.0})
                g.attrs["message"] = "settle error too large" if fail else "ok"

        cfgs = f.create_group("configurations")
        for c in spec.configs:
            s = settings_of(c.key)
            g = cfgs.create_group(f"config_{c.key:02d}")
            g.attrs["key"] = c.key
            for name, value in s.items():
                g.attrs[name] = value
            g.attrs["n_trials"] = c.n_trials
            g.attrs["status"] = c.status
            robot_rom = np.asarray(s["robot_rom.range_deg"], dtype=float)
            lo, hi = c.angle_range_deg or (float(robot_rom[0]), float(robot_rom[1]))
            mid, amp = (lo + hi) / 2.0, (hi - lo) / 2.0
            period = 2.0 * math.pi * amp / float(s["speed.speed_deg_s"])  # type: ignore[arg-type]  # Eq 25
            b = ellipse_b_for_energy(c.energy_j, amp)
            energies: list[float] = []
            cycle_trial: list[int] = []
            n_trials_written = c.n_trials if c.status != "not run" else 0
            for trial in range(1, n_trials_written + 1):
                tg = g.create_group(f"trials/{trial}")
                phase = 2.0 * math.pi * time_s / period
                angle = mid + amp * np.sin(phase)
                brace = c.slope_nm_per_deg * (angle - 20.0) + b * np.cos(phase)
                robot = 10.0 * np.sin(np.radians(angle)) + 2.0 * np.cos(phase)
                for side, torque in (("brace_on", brace + robot), ("brace_off", robot)):
                    rg = tg.create_group(side)
                    noisy = torque + rng.normal(0.0, 0.05, n)
                    _ds(rg, "time_s", time_s, "s")
                    _ds(rg, "angle_deg", angle, "deg")
                    _ds(rg, "torque_nm", noisy, "N*m")
                    _ds(rg, "angle_codes", np.round(angle * 10).astype(np.int16), "counts", gzip=True)
                    _ds(rg, "torque_codes", np.round(noisy * 20).astype(np.int16), "counts", gzip=True)
                    cmd = mid + amp * np.sin(2.0 * math.pi * cmd_time / period)
                    _ds(rg, "command_time_s", cmd_time, "s")
                    _ds(rg, "command_deg", cmd, "deg")
                    _ds(rg, "command_volts", cmd / 13.0 - 5.0, "V")
                    _ds(
                        rg,
                        "command_codes",
                        np.round(32768 + 3276.8 * (cmd / 13.0 - 5.0)).astype(np.uint16),
                        "counts",
                        gzip=True,
                    )
                    _ds(rg, "tick_lateness_s", np.zeros(n_cmd), "s")
                    rg.attrs["step_id"] = f"{s['set']}:config_{c.key:02d}:trial_{trial}:{side}"
                    rg.attrs["brace"] = side.split("_")[1]
                    rg.attrs["trajectory"] = json.dumps({"profile": "sinusoid", "mean_deg": mid})
                    rg.attrs["tick_lateness_p99_s"] = 0.0
                    rg.attrs["tick_lateness_max_s"] = 0.0
                    rg.attrs["started_utc"] = "2026-11-21T10:15:05Z"
                    if side == "brace_off":
                        sc = rg.create_group("scaling")
                        _ds(sc, "iteration", np.arange(1, 3), "1")
                        _ds(sc, "scale", np.ones(2), "1")
                        _ds(sc, "input_range_deg", np.tile([lo, hi], (2, 1)), "deg")
                        _ds(sc, "output_range_deg", np.tile([lo, hi], (2, 1)), "deg")
                        # the kept (second) run within 0.1 deg, but trial 2's left outside it
                        kept_error = 0.25 if trial == 2 else 0.02 * trial
                        _ds(sc, "range_error_deg", np.array([0.6, kept_error]), "deg")
                        sc.attrs["converged"] = trial != 2
                        sc.attrs["kept_iteration"] = 2
                pg = tg.create_group("processed")
                _ds(pg, "time_s", time_s, "s")
                _ds(pg, "angle_deg", angle, "deg")
                _ds(pg, "brace_torque_nm", brace, "N*m")
                pg.attrs["transition_index0_on"] = 0
                pg.attrs["transition_index0_off"] = 0
                pg.attrs["subtraction"] = "equal_angle"
                pg.attrs["filter"] = json.dumps({"kind": "butterworth", "order": 10})
                pg.attrs["coverage"] = 1.0 - 0.01 * trial
                n_cycles = int(spec.duration_s // period)
                for _ in range(n_cycles):
                    energies.append(c.energy_j * (1.0 + c.energy_spread * rng.standard_normal()))
                    cycle_trial.append(trial)
            if n_trials_written:
                _ds(g, "energy_loss_j", np.asarray(energies), "J")
                _ds(g, "energy_cycle_trial", np.asarray(cycle_trial, dtype=np.int64), "1")
                bw = g.create_group("fits/bouc_wen")
                bw.attrs["A"] = 0.2823
                bw.attrs["n"] = 1.2065
                bw.attrs["beta"] = np.asarray([0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036])
                bw.attrs["rmse_nm"] = 0.8
                bw.attrs["r2"] = 0.97
                bw.attrs["A_std"] = 0.01
                bw.attrs["n_std"] = 0.05
                bw.attrs["beta_std"] = np.full(6, 0.002)
                theta = np.asarray([0.2823, 1.2065, 0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036])
                bw.attrs["param_interval_low"] = theta - 1.96 * np.asarray([0.01, 0.05, *[0.002] * 6])
                bw.attrs["param_interval_high"] = theta + 1.96 * np.asarray([0.01, 0.05, *[0.002] * 6])
                bw.attrs["cv_rmse_nm"] = np.full(max(n_trials_written, 1), 0.9)
                bw.attrs["n_starts"] = 8
                x = (angle - angle.mean())[::20]
                y = (brace - brace.mean())[::20]
                _ds(bw, "angle_deg", x, "deg")
                _ds(bw, "torque_nm", y, "N*m")
                _ds(bw, "model_torque_nm", y * 0.95, "N*m")
                spring_k = STIFFNESS_N_PER_MM[str(s["stiffness"])]
                el = g.create_group("fits/elements")
                el.attrs["rmse_nm"] = 2.5
                el.attrs["rmse_all_samples_nm"] = 2.9
                el.attrs["applicable"] = spring_k > 0.0
                el.attrs["reason"] = "" if spring_k > 0.0 else "no elastic element has a free parameter"
                el.attrs["target"] = "midline"
                el.attrs["springs.zero_offset_deg"] = 20.0 + c.key / 10.0
                fitted = dict(device_of(c.key)[2], zero_offset_deg=20.0 + c.key / 10.0)
                el.attrs["elements_json"] = json.dumps([fitted])
                grid = np.linspace(lo, hi, 200)
                _ds(el, "angle_deg", grid, "deg")
                _ds(el, "torque_nm", c.slope_nm_per_deg * (grid - 20.0) + 0.1, "N*m")
                _ds(el, "model_torque_nm", c.slope_nm_per_deg * (grid - 20.0), "N*m")

        if spec.comparisons:
            keys_present = {c.key for c in spec.configs}
            comps = f.create_group("comparisons")
            for name, (parameter, section, title, keys) in {
                **THESIS_COMPARISONS,
                **spec.extra_comparisons,
            }.items():
                if not set(keys) & keys_present and name not in spec.extra_comparisons:
                    continue
                cg = comps.create_group(name)
                cg.attrs["parameter"] = parameter
                cg.attrs["section"] = section
                cg.attrs["title"] = title
                cg.attrs["configurations"] = np.asarray(keys, dtype=np.int64)
                cg.attrs["energy_mean_j"] = np.zeros(len(keys))
                cg.attrs["energy_std_j"] = np.zeros(len(keys))
        if spec.reference:
            rg = f.create_group("reference/emu_schmidt")
            ang = np.linspace(5, 105, 300)
            _ds(rg, "angle_deg", ang, "deg")
            _ds(rg, "torque_nm", 0.25 * (ang - 20.0), "N*m")
            rg.attrs["source"] = "correcteddata.mat"
            rg.attrs["title"] = "Schmidt EMU data"
    return path


def thesis_like_specs(n_trials: int = 2) -> list[ConfigSpec]:
    """Configurations 1-14 with energies, ranges and slopes that follow every Chapter 5 finding."""
    energy = {
        1: 4.0,
        2: 5.5,
        3: 6.0,
        4: 3.0,
        5: 4.0,
        6: 6.0,
        7: 8.0,
        8: 5.0,
        9: 7.0,
        10: 6.0,
        11: 6.5,
        12: 2.0,
        13: 4.5,
        14: 6.0,
    }
    ranges = {1: (25.0, 105.0), 2: (8.0, 110.0), 3: (5.0, 109.0)}
    specs = [
        ConfigSpec(key=k, energy_j=e, n_trials=n_trials, angle_range_deg=ranges.get(k))
        for k, e in energy.items()
    ]
    for k in (4, 5, 6, 7, 8, 9, 10, 11, 14):
        specs[k - 1].angle_range_deg = (5.0, 109.0)
    return specs


# Energies (J per cycle) of the four friction configurations of Appendix A (keys 4-7).
FRICTION_ENERGY_J = {4: 1.5, 5: 2.5, 6: 4.0, 7: 6.0}


def small_spec(**overrides: object) -> ArchiveSpec:
    """4 configurations (the friction set, keys 4-7) x 2 trials of 17 s (2 cycles each), with fits, events, checklists."""
    spec = ArchiveSpec(
        configs=[
            ConfigSpec(key=k, energy_j=e, n_trials=2, angle_range_deg=(5.0, 109.0))
            for k, e in FRICTION_ENERGY_J.items()
        ],
        duration_s=17.0,
        interrupted=True,
    )
    for name, value in overrides.items():
        setattr(spec, name, value)
    return spec
