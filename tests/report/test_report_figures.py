"""Figures: PNG data URIs at the report's resolution, each independent of the figures drawn before it, and
the same whether drawn serially or on worker processes."""

from __future__ import annotations

import base64
import struct
from pathlib import Path

from protocol_runner.protocol.plan_steps import Comparison
from protocol_runner.report.figure_plan import comparison_axis, figure_ids
from protocol_runner.report.figures import (
    DPI,
    LAYOUTS,
    assemble_figures,
    bouc_wen_figure,
    energy_bars_figure,
    energy_cycles_figure,
    hysteresis_figure,
)
from protocol_runner.report.load import load_report_data
from protocol_runner.report.model import Configuration


def _png(uri: str) -> bytes:
    prefix = "data:image/png;base64,"
    assert uri.startswith(prefix)
    raw = base64.b64decode(uri[len(prefix) :], validate=True)
    assert raw[:8] == b"\x89PNG\r\n\x1a\n"
    return raw


def _size(raw: bytes) -> tuple[int, int]:
    width, height = struct.unpack(">II", raw[16:24])
    return width, height


def _config(small_archive: Path, key: int) -> Configuration:
    cfg = load_report_data(small_archive).configuration(key)
    assert cfg is not None
    return cfg


def test_hysteresis_figure_is_a_small_png_at_report_resolution(small_archive: Path) -> None:
    width, height = _size(_png(hysteresis_figure(_config(small_archive, 4))))
    width_in, height_in, _ = LAYOUTS["single"]
    assert (width, height) == (round(width_in * DPI), round(height_in * DPI))


def test_a_figure_does_not_depend_on_the_figures_drawn_before_it(small_archive: Path) -> None:
    a, b = _config(small_archive, 4), _config(small_archive, 7)
    first = hysteresis_figure(a)
    other = hysteresis_figure(b)
    energy_cycles_figure(b)  # same layout, different content and axis limits
    again = hysteresis_figure(a)
    assert first == again
    assert first != other


def test_a_two_panel_figure_is_drawn_again_byte_for_byte(small_archive: Path) -> None:
    a, b = _config(small_archive, 5), _config(small_archive, 6)
    first = bouc_wen_figure(a)
    bouc_wen_figure(b)
    assert bouc_wen_figure(a) == first


def test_bar_chart_after_a_line_chart_restores_numeric_ticks(small_archive: Path) -> None:
    data = load_report_data(small_archive)
    friction = next(c for c in data.comparisons if c.name == "friction")
    assert friction is not None
    bars = energy_bars_figure(data, friction)
    hysteresis_figure(_config(small_archive, 4))
    assert energy_bars_figure(data, friction) == bars


def test_serial_and_parallel_rendering_give_identical_images(small_archive: Path) -> None:
    data = load_report_data(small_archive)
    serial = assemble_figures(data, 1)
    parallel = assemble_figures(data, 2)
    assert serial.missing == {} and parallel.missing == {}
    assert set(serial.images) == set(figure_ids(data))
    assert serial.images == parallel.images


def _axis(data, parameter: str, keys=(4, 5, 6, 7)):
    configs = [c for k in keys if (c := data.configuration(k)) is not None]
    return comparison_axis(
        Comparison(name="c", parameter=parameter, title="c", section="", configurations=tuple(keys)), configs
    )


def test_labels_carry_the_level_and_the_varying_quantity_with_its_unit(small_archive: Path) -> None:
    data = load_report_data(small_archive)
    cfg = data.configuration(7)
    friction = _axis(data, "friction")
    # friction_nm is the first quantity that differs across 4-7: the numeric axis, in N·m from `_nm`
    assert (friction.quantity, friction.numeric) == ("friction_nm", True)
    assert friction.label == "friction: friction (N·m)"
    assert friction.config_label(cfg) == "7: 3 (6.25 N·m)"
    assert [friction.value(c) for c in data.configurations] == [0.0, 1.25, 3.75, 6.25]
    # a factor that does not vary here still labels by its level and first quantity
    brace = _axis(data, "brace_rom")
    assert (brace.quantity, brace.numeric, brace.label) == ("range_deg", False, "brace_rom: range (deg)")
    assert brace.config_label(cfg) == "7: R3 (0–130 deg), friction 3"  # friction also differs: shown
    assert _axis(data, "trajectory").config_label(cfg) == "7: sine, friction 3"


def test_a_range_quantity_is_a_label_and_a_scalar_one_a_numeric_axis(tmp_path: Path) -> None:
    from tests.report.report_archive_builder import ArchiveSpec, ConfigSpec, write_archive

    spec = ArchiveSpec(configs=[ConfigSpec(key=k) for k in (1, 2, 3, 10, 11)], duration_s=10.0)
    data = load_report_data(write_archive(tmp_path / "a.h5", spec))
    rom = _axis(data, "brace_rom", (1, 2, 3))
    assert (rom.quantity, rom.numeric) == ("range_deg", False)
    assert [rom.value_text(data.configuration(k)) for k in (1, 2, 3)] == [
        "R1 (40–90 deg)",
        "R2 (20–110 deg)",
        "R3 (0–130 deg)",
    ]
    speed = _axis(data, "speed", (10, 11))
    assert (speed.numeric, speed.label) == (True, "speed: speed (deg/s)")
    assert [speed.value(data.configuration(k)) for k in (10, 11)] == [50.0, 25.0]


def test_energy_figure_puts_each_configuration_at_its_factor_value(small_archive: Path, monkeypatch) -> None:
    data = load_report_data(small_archive)
    friction = next(c for c in data.comparisons if c.name == "friction")
    assert friction is not None
    fig = _drawn(monkeypatch, lambda: energy_bars_figure(data, friction))
    (ax,) = fig.axes
    assert ax.get_xlabel() == "friction: friction (N·m)"
    (line,) = [ln for ln in ax.get_lines() if ln.get_marker() == "o"]
    assert list(line.get_xdata()) == [0.0, 1.25, 3.75, 6.25]
    means = [data.configuration(k).energy_mean_j for k in (4, 5, 6, 7)]
    assert list(line.get_ydata()) == means


def _drawn(monkeypatch, draw) -> object:
    """The matplotlib Figure a figure function draws (captured before it becomes a PNG)."""
    from protocol_runner.report import figures

    captured = []
    real = figures.to_data_uri

    def keep(fig):
        captured.append(fig)
        return real(fig)

    monkeypatch.setattr(figures, "to_data_uri", keep)
    draw()
    return captured[-1]


def test_hysteresis_figure_draws_one_loop_per_processed_trial_over_its_data(
    small_archive: Path, monkeypatch
) -> None:
    cfg = _config(small_archive, 4)
    processed = [t.processed for t in cfg.trials if t.processed is not None]
    fig = _drawn(monkeypatch, lambda: hysteresis_figure(cfg))
    (ax,) = fig.axes
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("Angle (deg)", "Torque (N·m)")
    loops = [line for line in ax.get_lines() if line.get_label().startswith("trial ")]
    assert len(loops) == len(processed) >= 1
    for line, p in zip(loops, processed, strict=True):
        x, y = line.get_data()
        assert (min(x), max(x)) == (p.angle_deg.min(), p.angle_deg.max())
        assert (min(y), max(y)) == (p.brace_torque_nm.min(), p.brace_torque_nm.max())


def test_energy_cycles_figure_draws_every_cycle_and_the_mean(small_archive: Path, monkeypatch) -> None:
    cfg = _config(small_archive, 4)
    fig = _drawn(monkeypatch, lambda: energy_cycles_figure(cfg))
    (ax,) = fig.axes
    assert ax.get_ylabel() == "Energy per cycle (J)"
    points = [line for line in ax.get_lines() if line.get_label().startswith("trial ")]
    drawn = sorted(float(v) for line in points for v in line.get_ydata())
    assert drawn == sorted(cfg.energy_loss_j.tolist())
    means = [line for line in ax.get_lines() if line.get_label().startswith("mean ")]
    assert len(means) == 1 and means[0].get_ydata()[0] == cfg.energy_mean_j


def test_element_fits_are_drawn_for_the_comparisons_that_change_a_fitted_element(
    tmp_path: Path, monkeypatch
) -> None:
    from protocol_runner.report.figure_plan import model_comparisons
    from protocol_runner.report.figures import element_fit_figure
    from tests.report.report_archive_builder import ArchiveSpec, ConfigSpec, write_archive

    keys = (4, 5, 6, 7, 14, 17, 20, 23)
    spec = ArchiveSpec(configs=[ConfigSpec(key=k, n_trials=1) for k in keys], duration_s=9.0)
    data = load_report_data(write_archive(tmp_path / "a.h5", spec))
    # the springs (the fitted element) differ only across the stiffness group; the friction group
    # changes the brake, which is not fitted
    assert [c.name for c in model_comparisons(data)] == ["stiffness"]
    comp = next(c for c in data.comparisons if c.name == "stiffness")
    assert comp is not None
    fig = _drawn(monkeypatch, lambda: element_fit_figure(data, comp))
    (ax,) = fig.axes
    models = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]
    # K0 (config 17) has no spring: its fit is not applicable and draws nothing
    assert [ln.get_label().split(",")[0] for ln in models] == [
        "20: K1 (4.4 N/mm)",
        "14: K2 (13 N/mm)",
        "23: K3 (20 N/mm)",
    ]
    for line, key in zip(models, (20, 14, 23), strict=True):
        fit = data.configuration(key).element_fit
        assert list(line.get_ydata()) == list(fit.model_torque_nm)
    # the midline the model was fitted to is drawn too (solid with dots), in the model's colour
    midlines = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-" and ln.get_marker() == "o"]
    assert len(midlines) == 3
    for midline, model, key in zip(midlines, models, (20, 14, 23), strict=True):
        fit = data.configuration(key).element_fit
        assert fit.torque_nm.size > 0
        assert list(midline.get_xdata()) == list(fit.angle_deg)
        assert list(midline.get_ydata()) == list(fit.torque_nm)
        assert midline.get_color() == model.get_color()
    # K0 is named in the key as not fitted, with nothing drawn for it
    (unfitted,) = [ln for ln in ax.get_lines() if "not fitted" in ln.get_label()]
    assert unfitted.get_label().startswith("17: ") and len(unfitted.get_xdata()) == 0


def test_energy_cycles_figure_counts_cycles_in_whole_numbers(small_archive: Path, monkeypatch) -> None:
    """Two cycles once had ticks at 1.00, 1.25, ... 2.00: a cycle number is a count."""
    import dataclasses

    cfg = _config(small_archive, 4)
    for n in (2, 3, 7):
        few = dataclasses.replace(
            cfg, energy_loss_j=cfg.energy_loss_j[:n], energy_cycle_trial=cfg.energy_cycle_trial[:n]
        )
        fig = _drawn(monkeypatch, lambda few=few: energy_cycles_figure(few))
        (ax,) = fig.axes
        lo, hi = ax.get_xlim()
        shown = [t for t in ax.get_xticks() if lo <= t <= hi]
        assert len(shown) >= 2 and all(float(t).is_integer() for t in shown), (n, shown)
