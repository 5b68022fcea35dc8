"""Sliders for the labs (ipywidgets), with a static figure where widgets cannot be shown.

Each explorer takes the student's own functions, so moving a slider reruns *their*
code: the beam model's mixture weights and noise against its density and the
likelihood map (lab 02), the particle filter's noise levels and particle count
(lab 03), MCL's particle count and motion-noise alphas (lab 05).

:func:`interact_or_static` is the one place that decides: in a running IPython kernel
with ipywidgets importable it shows the sliders and, below them, the figure at the
sliders' initial values as an ordinary image output, which each move of a slider
replaces (through a display handle). A widget's state is not saved with a notebook, so
this way a notebook run headless (nbconvert, nbval, CI) or opened in a viewer still
shows the figure. Elsewhere (a script, no ipywidgets) it draws the figure once.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from robolab.plotting.core import legend_outside, plot_map
from robolab.progress import in_kernel

__all__ = [
    "Slider",
    "interact_or_static",
    "widgets_available",
    "beam_model_explorer",
    "landmark_pf_explorer",
    "mcl_explorer",
]


@dataclass(frozen=True)
class Slider:
    """A numeric control: ``value`` within ``[low, high]`` in steps of ``step``."""

    low: float
    high: float
    step: float
    value: float
    description: str = ""
    integer: bool = False

    def __post_init__(self) -> None:
        if not self.low <= self.value <= self.high or self.step <= 0:
            raise ValueError(f"slider {self.description!r}: need low <= value <= high, step > 0; "
                             f"got {self.low}, {self.value}, {self.high}, step {self.step}")

    def widget(self):
        import ipywidgets as w

        kind = w.IntSlider if self.integer else w.FloatSlider
        cast = int if self.integer else float
        return kind(min=cast(self.low), max=cast(self.high), step=cast(self.step),
                    value=cast(self.value), description=self.description,
                    continuous_update=False, style={"description_width": "initial"})


def widgets_available() -> bool:
    """True inside an IPython kernel with ipywidgets importable."""
    return in_kernel()


def interact_or_static(draw: Callable[..., Figure], **sliders: Slider):
    """Sliders that redraw ``draw(**values)``, above the figure at their initial values.

    ``draw`` returns the Figure it made. Without a kernel and ipywidgets the figure is
    drawn once at the defaults (``plt.show()``).

    Returns
    -------
    The ``ipywidgets`` box of sliders (already displayed), or None for the static figure.
    """
    defaults = {name: (int(s.value) if s.integer else s.value) for name, s in sliders.items()}
    if not widgets_available():
        draw(**defaults)
        plt.show()
        return None
    import ipywidgets as w
    from IPython.display import display

    controls = {name: s.widget() for name, s in sliders.items()}
    box = w.VBox(list(controls.values()))
    display(box)

    def render(values: dict):
        fig = draw(**values)
        plt.close(fig)  # shown through the handle only, not again at the end of the cell
        return fig

    handle = display(render(defaults), display_id=True)

    def redraw(_change) -> None:
        handle.update(render({name: c.value for name, c in controls.items()}))

    for control in controls.values():
        control.observe(redraw, names="value")
    box.redraw = redraw  # for tests and for a caller that changes several values at once
    return box


def beam_model_explorer(
    beam_range_finder_model: Callable,
    pose_likelihood_map: Callable,
    scan,
    grid,
    beam_angles,
    params: dict,
    *,
    z_star: float = 3.0,
    true_pose=None,
    lattice: float = 0.25,
):
    """Lab 02: mixture weights, ``sigma_hit`` and ``lambda_short`` against p(z | z*) and the map.

    The left panel is the student's mixture for one beam with expected range ``z_star``;
    the right one the best-heading scan log-likelihood over a ``lattice``-metre grid of
    positions (coarse, so that a redraw takes a fraction of a second).
    """
    from robolab.plotting.beam_model import lattice_positions

    xs, ys, positions = lattice_positions(grid, lattice)
    headings = np.deg2rad(np.arange(-180, 180, 45))
    z_max = float(params["max_range"])
    z = np.linspace(0.0, np.nextafter(z_max, 0.0), 600)

    def draw(z_hit, z_short, z_max_weight, z_rand, sigma_hit, lambda_short):
        weights = np.array([z_hit, z_short, z_max_weight, z_rand], dtype=float)
        if weights.sum() <= 0:
            weights = np.array([1.0, 0.0, 0.0, 0.0])
        weights = weights / weights.sum()  # the sliders need not sum to 1; the model must
        prm = dict(params, z_hit=weights[0], z_short=weights[1], z_max=weights[2],
                   z_rand=weights[3], sigma_hit=sigma_hit, lambda_short=lambda_short)
        density = beam_range_finder_model(z[:, None], np.full((z.size, 1), z_star), prm)
        log_l = np.asarray(pose_likelihood_map(scan, grid, beam_angles, prm, positions, headings))
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.6))
        a1.plot(z, np.asarray(density, dtype=float).ravel(), color="tab:purple",
                label="p(z | z*), continuous part")
        a1.axvline(z_star, color="k", ls="--", lw=0.8, label=f"z* = {z_star:g} m")
        a1.set(title="Mixture for one beam (weights normalized)", xlabel="measured range z [m]",
               ylabel="density [1/m]")
        legend_outside(a1, loc="upper right", bbox_to_anchor=(1.0, 1.0))
        best = log_l.max(axis=1).reshape(ys.size, xs.size)
        plot_map(grid, a2, title="Scan log-likelihood, best heading")
        im = a2.imshow(np.maximum(best, best.max() - 100.0), origin="lower", cmap="magma",
                       alpha=0.85, extent=(xs[0] - lattice / 2, xs[-1] + lattice / 2,
                                           ys[0] - lattice / 2, ys[-1] + lattice / 2))
        fig.colorbar(im, ax=a2, label="log p(z | x, m) [nats]")
        if true_pose is not None:
            a2.plot(true_pose[0], true_pose[1], "o", mfc="none", mec="tab:cyan", mew=2, ms=12,
                    label="true pose")
            legend_outside(a2, loc="lower left", bbox_to_anchor=(0.0, 1.08))
        a2.set(xlabel="x [m]", ylabel="y [m]")
        fig.tight_layout()
        return fig

    return interact_or_static(
        draw,
        z_hit=Slider(0.0, 1.0, 0.05, float(params["z_hit"]), "z_hit"),
        z_short=Slider(0.0, 1.0, 0.05, float(params["z_short"]), "z_short"),
        z_max_weight=Slider(0.0, 1.0, 0.05, float(params["z_max"]), "z_max weight"),
        z_rand=Slider(0.0, 1.0, 0.05, float(params["z_rand"]), "z_rand"),
        sigma_hit=Slider(0.02, 1.0, 0.02, float(params["sigma_hit"]), "sigma_hit [m]"),
        lambda_short=Slider(0.05, 3.0, 0.05, float(params["lambda_short"]), "lambda_short [1/m]"),
    )


def landmark_pf_explorer(particle_filter: Callable, world, controls, measurements, true_path,
                         *, seed: int = 0):
    """Lab 03: noise levels and particle count against the filter's path and error."""
    true_path = np.asarray(true_path, dtype=float)

    def draw(forward_noise, turn_noise, sensor_noise, log10_particles):
        n = int(round(10**log10_particles))
        noise = {"forward_noise": forward_noise, "turn_noise": turn_noise,
                 "sensor_noise": sensor_noise}
        path = np.asarray(particle_filter(world, controls, measurements, n, noise,
                                          np.random.default_rng(seed)), dtype=float)
        err = np.linalg.norm(path[:, :2] - true_path[:, :2], axis=1)
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.8))
        a1.plot(true_path[:, 0], true_path[:, 1], "g-o", ms=4, label="true path")
        a1.plot(path[:, 0], path[:, 1], "b-x", ms=6, label="estimate")
        lm = np.asarray(world.landmarks, dtype=float)
        a1.scatter(lm[:, 0], lm[:, 1], marker="*", s=140, c="k", label="landmarks")
        a1.set(title=f"Particle filter with N = {n}", xlabel="x [m]", ylabel="y [m]",
               xlim=(0, world.size), ylim=(0, world.size), aspect="equal")
        legend_outside(a1)
        a2.plot(np.arange(len(err)), err, "b-o", ms=4)
        a2.set(title=f"Position error (mean {err.mean():.2f} m)", xlabel="step",
               ylabel="position error [m]")
        fig.tight_layout()
        return fig

    return interact_or_static(
        draw,
        forward_noise=Slider(0.5, 20.0, 0.5, 5.0, "forward noise [m]"),
        turn_noise=Slider(0.01, 0.5, 0.01, 0.1, "turn noise [rad]"),
        sensor_noise=Slider(0.5, 20.0, 0.5, 5.0, "sensor noise [m]"),
        log10_particles=Slider(1.0, 4.0, 0.25, 3.0, "log10 N"),
    )


def mcl_explorer(data, mcl_step: Callable, init_gaussian: Callable, field, params: dict, *,
                 seconds: float = 15.0, seed: int = 0):
    """Lab 05: particle count and the motion-noise alphas against tracking error over time.

    Each redraw tracks the first ``seconds`` of the bag from a Gaussian start around the
    true pose, every third scan, with the student's ``mcl_step``.
    """
    from robolab.plotting.mcl import run_mcl

    def draw(n_particles, alpha_rot, alpha_trans):
        rng = np.random.default_rng(seed)
        start = init_gaussian(data.truth[0], np.diag([0.1**2, 0.1**2, 0.1**2]), n_particles, rng)
        prm = dict(params, alphas=(alpha_rot, alpha_trans, alpha_trans, alpha_rot))
        run = run_mcl(data, mcl_step, start, field, prm, rng, every=3, t_end=seconds,
                      snapshot_times=(), progress=False)
        fig, ax = plt.subplots(figsize=(9, 3.8))
        ax.plot(run["t"], run["position_error"], label="position error")
        ax.set(title=f"Tracking with {n_particles} particles, alphas ({alpha_rot:g}, "
                     f"{alpha_trans:g}, {alpha_trans:g}, {alpha_rot:g})",
               xlabel="time [s]", ylabel="position error [m]", yscale="log")
        legend_outside(ax)
        fig.tight_layout()
        return fig

    return interact_or_static(
        draw,
        n_particles=Slider(50, 3000, 50, 500, "particles", integer=True),
        alpha_rot=Slider(0.0, 1.0, 0.02, float(params["alphas"][0]), "alpha 1, 4 (rotation)"),
        alpha_trans=Slider(0.0, 1.0, 0.02, float(params["alphas"][1]),
                           "alpha 2, 3 (translation)"),
    )
