"""The ``mu-slip`` page: the EKF's convergence and its animation, the curve families'
fits, and what the two-parameter curve's shape leaves out."""

from __future__ import annotations

import io
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from brakethermo.report.page import Card, Page, Section, TableBlock, consistency_text
from brakethermo.results.mu_slip import MuSlipResult
from brakethermo.rigs.tyre import rudd_mu


def _ellipse(P: np.ndarray, n: int = 60) -> np.ndarray:
    """1σ contour of a 2-D Gaussian around 0: points (n, 2)."""
    w, V = np.linalg.eigh(P)
    a = np.linspace(0.0, 2.0 * np.pi, n)
    return (V @ (np.sqrt(np.maximum(w, 0.0))[:, None] * np.stack([np.cos(a), np.sin(a)]))).T


def animation_gif(res: MuSlipResult, frames: int = 30, max_points: int = 300) -> bytes:
    """GIF of the EKF: data so far, estimated curve, peak and its 1σ ellipse, per frame.

    The axes, ticks and the thinned cloud of all points are drawn once; each frame
    restores that background and draws only its own artists (blitting), so a frame
    costs milliseconds rather than a full figure draw. At most ``max_points`` points
    are drawn (evenly thinned).
    """
    from PIL import Image

    K = res.slip.size
    idx = np.unique(np.linspace(0, K - 1, frames).astype(int))
    x, P = res.ekf.x_filt, res.ekf.P_filt
    fig, ax = plt.subplots(figsize=(6, 4), dpi=72)
    s_grid = np.linspace(0.0, max(1.0, float(res.slip.max())), 200)
    thin = np.unique(np.linspace(0, K - 1, min(K, max_points)).astype(int))
    ax.plot(res.slip[thin], res.mu[thin], ".", color="0.8", ms=2)
    ax.set_xlim(0, s_grid[-1])
    ax.set_ylim(0, 1.4 * max(float(np.nanmax(res.mu)), 0.1))
    ax.set_xlabel("slip (–)")
    ax.set_ylabel("μ (–)")
    ax.set_title("EKF on the two-parameter curve: estimate and 1σ ellipse")
    fig.tight_layout()
    pts, curve, ell, pk = (
        ax.plot([], [], ".", color="tab:green", ms=2, animated=True)[0],
        ax.plot([], [], color="tab:red", animated=True)[0],
        ax.plot([], [], color="tab:blue", animated=True)[0],
        ax.plot([], [], "o", color="tab:red", animated=True)[0],
    )
    label = ax.text(0.02, 0.95, "", transform=ax.transAxes, va="top", animated=True)
    canvas = fig.canvas
    canvas.draw()
    background = canvas.copy_from_bbox(fig.bbox)
    images = []
    for k in idx:
        shown = thin[thin <= k]
        pts.set_data(res.slip[shown], res.mu[shown])
        curve.set_data(s_grid, rudd_mu(s_grid, x[k, 0], x[k, 1]))
        e = _ellipse(P[k])
        ell.set_data(x[k, 1] + e[:, 1], x[k, 0] + e[:, 0])
        pk.set_data([x[k, 1]], [x[k, 0]])
        label.set_text(f"point {k + 1}/{K}: μp {x[k, 0]:.3f}, sp {x[k, 1]:.3f}")
        canvas.restore_region(background)
        for artist in (pts, curve, ell, pk, label):
            ax.draw_artist(artist)
        canvas.blit(fig.bbox)
        rgba = np.asarray(canvas.buffer_rgba())
        images.append(Image.fromarray(rgba[..., :3].copy()).quantize(colors=64))
    plt.close(fig)
    buf = io.BytesIO()
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:], duration=150,
                   loop=0)
    return buf.getvalue()


def page(res: MuSlipResult, summ: dict[str, Any]) -> Page:
    """The report page: convergence, curve fits, the families and the shape mismatch."""
    fig = _convergence_figure(res)
    fig2 = _fits_figure(res)
    rows = _estimator_rows(summ)
    fam_rows = [
        [f.name, f"{f.rmse:.4f}", f"{f.heldout_rmse:.4f}", f"{f.mu_peak:.3f}", f"{f.slip_peak:.3f}"]
        for f in res.families
    ]
    mm = summ["shape_mismatch"]
    return Page(
        title=f"mu-slip — {res.session.path.name}",
        subtitle="tyre μ–slip peak: EKF, Levenberg–Marquardt and curve families",
        cards=[
            Card("peak μ", f"{res.best.mu_peak:.3f} ± {summ['peak']['mu_std']:.3f}", "1σ"),
            Card("peak slip", f"{res.best.slip_peak:.3f} ± {summ['peak']['slip_std']:.3f}",
                 "1σ"),
            Card("from", res.best.name),
            Card("points", str(res.slip.size)),
        ],
        sections=[
            Section(
                "Two-parameter curve (Rudd)",
                paragraphs=[_rudd_text(res, summ)],
                tables=[TableBlock(["estimator", "μ peak", "slip peak"], rows)],
                figures={"ekf_convergence": fig},
                notes=[
                    "Animation of the EKF (curve and 1σ ellipse after each point):"
                    " ekf_animation.gif beside this page."
                ],
            ),
            Section(
                "Curve families",
                paragraphs=[mm["words"] + "."] + ([summ["relaxation"]["words"] + "."]
                                                  if summ.get("relaxation") else []),
                tables=[
                    TableBlock(
                        ["family", "RMSE", "held-out RMSE", "μ peak", "slip peak"],
                        fam_rows,
                        caption="5-fold cross-validation",
                    )
                ],
                figures={"curve_fits": fig2},
            ),
        ],
    )


def _convergence_figure(res: MuSlipResult) -> Figure:
    """The EKF's peak μ and slip with their 1σ bands, and its covariance, point by point."""
    x, P = res.ekf.x_filt, res.ekf.P_filt
    k = np.arange(1, res.slip.size + 1)
    fig, axs = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    for j, (name, ax) in enumerate(zip(("μ peak", "slip peak"), axs[:2], strict=True)):
        sd = np.sqrt(P[:, j, j])
        ax.fill_between(k, x[:, j] - sd, x[:, j] + sd, alpha=0.3)
        ax.plot(k, x[:, j])
        ax.set_ylabel(f"{name} (–)")
    axs[2].plot(k, P[:, 0, 0] / P[0, 0, 0], label="var μp / initial")
    axs[2].plot(k, P[:, 1, 1] / P[0, 1, 1], label="var sp / initial")
    axs[2].plot(k, P[:, 0, 1] / np.sqrt(P[:, 0, 0] * P[:, 1, 1]), label="correlation")
    axs[2].set_xlabel("point")
    axs[2].legend(fontsize=8)
    fig.tight_layout()
    return fig


def _fits_figure(res: MuSlipResult) -> Figure:
    """The points with every family's curve and the EKF's two-parameter curve."""
    fig2, ax2 = plt.subplots(figsize=(9, 4))
    ax2.plot(res.slip, res.mu, ".", color="0.7", ms=2, label="points")
    sg = np.linspace(1e-4, float(res.slip.max()), 400)
    for f in res.families:
        ax2.plot(sg, f(sg), label=f"{f.name} (held-out {f.heldout_rmse:.4f})")
    ax2.plot(sg, rudd_mu(sg, *res.ekf.x_filt[-1]), "--", label="EKF (one pass)")
    ax2.set_xlabel("slip (–)")
    ax2.set_ylabel("μ (–)")
    ax2.legend(fontsize=8)
    fig2.tight_layout()
    return fig2


def _estimator_rows(summ: dict[str, Any]) -> list[list[str]]:
    """The peak μ and slip ± 1σ of the EKF and the two Levenberg–Marquardt fits."""
    rows = [
        [
            "EKF (one pass)",
            f"{summ['ekf']['mu_peak']:.3f} ± {summ['ekf']['mu_peak_std']:.3f}",
            f"{summ['ekf']['slip_peak']:.3f} ± {summ['ekf']['slip_peak_std']:.3f}",
        ]
    ]
    for key, lab in (("lm_one_pass", "LM, one pass"), ("lm_converged", "LM, converged")):
        rows.append(
            [
                lab,
                f"{summ[key]['mu_peak']:.3f} ± {summ[key]['mu_peak_std']:.3f}",
                f"{summ[key]['slip_peak']:.3f} ± {summ[key]['slip_peak_std']:.3f}",
            ]
        )
    return rows


def _rudd_text(res: MuSlipResult, summ: dict[str, Any]) -> str:
    """Where the points came from, their noise, and what the EKF's innovations say."""
    return (
        (f"A set of {res.slip.size} (slip, μ) points, no time ramp;" if res.points
         else f"Ramp {res.ramp_s[0]:.2f}–{res.ramp_s[1]:.2f} s of the first"
              " braking;")
        +
        f" noise std of μ {res.sigma:.4f} (from point-to-point differences), inflated"
        f" ×{res.inflation:g} plus second-order pseudo-noise in the EKF; its"
        f" innovations: {consistency_text(summ['ekf_consistency'])}"
        + ("." if res.ekf_noise_scale == 1.0 else
           f"; its band widened {np.sqrt(res.ekf_noise_scale):.2f}x to their"
           " size (its peak is the same).")
    )
