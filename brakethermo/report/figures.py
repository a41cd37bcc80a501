"""Figures of the per-lap report, built once per session and refilled for every lap.

Creating a matplotlib figure costs far more than drawing it, and drawing the static
parts (axes, ticks, labels, legends, titles) costs more than drawing the data. So
:class:`LapFigures` creates its four figures and all their artists once; axis ranges
are rounded (time to 10 s, spot temperatures to 50 degC, the contact band's 1-sigma to
5 degC) or fixed for the session (contact band, speed, pressure), so similar laps share
one rendered background per figure:
:meth:`LapFigures.render` swaps the data of the animated artists, restores the cached
background and draws only those artists (blitting). All four figures share the same
width and horizontal margins, so stacked in the HTML page their time axes line up.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import PolyCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from PIL import Image

SPOT_COLOURS = ("#1f77b4", "#2ca02c", "#ff7f0e", "#d62728")  # spot1 (inner) .. spot4 (outer)
CONTACT_COLOUR = "#6a3d9a"
WINDOW_COLOUR = "#2ca02c"
ZONE_COLOUR = "#9e9e9e"
FIG_WIDTH = 11.0  # in
DPI = 100
LEFT, RIGHT = 0.07, 0.83  # figure fractions shared by every figure, so time axes align
MAX_ZONE_LABELS = 40
HEATMAP_ROWS = 96  # radial rows of the heat-map image

plt.rcParams.update(
    {
        "font.size": 10,
        "axes.titlesize": 11,
        "axes.labelsize": 10,
        "legend.fontsize": 9,
        "axes.grid": True,
        "grid.alpha": 0.3,
        "axes.spines.top": False,
    }
)


@dataclass(frozen=True)
class LapData:
    """What one lap's figures show; all arrays on the lap's 10 Hz grid.

    Attributes
    ----------
    t : ndarray — s
        Time from the lap start.
    spot, spot_std : ndarray, shape (4, n) — degC
        Estimated spot temperatures and their 1-sigma.
    measured : ndarray, shape (4, n) — degC
        Measured spot temperatures, NaN where a spot has no sensor.
    contact, contact_std : ndarray — degC
        Contact-band average and its 1-sigma.
    nodes : ndarray, shape (n_nodes, n) — degC
        Node temperatures.
    speed_kmh : ndarray — km/h
    pressure_bar : ndarray — bar
    zones_t : ndarray, shape (n_zones, 2) — s
        Start and end of each braking zone, lap time.
    zone_names : tuple of str
        Each zone's track name (B1…, as the zone table); its order in the lap without.
    """

    t: np.ndarray
    spot: np.ndarray
    spot_std: np.ndarray
    measured: np.ndarray
    contact: np.ndarray
    contact_std: np.ndarray
    nodes: np.ndarray
    speed_kmh: np.ndarray
    pressure_bar: np.ndarray
    zones_t: np.ndarray
    zone_names: tuple[str, ...] = ()


@dataclass(frozen=True)
class AxisScales:
    """Session-wide y ranges of the lap figures, so that laps compare at a glance.

    Attributes
    ----------
    spots : (float, float) — degC
        Used for a lap without any finite spot value (each lap otherwise gets its own
        range, rounded to 50 degC).
    contact : (float, float) — degC
    speed_kmh : float — km/h
        Top of the speed axis.
    pressure_bar : float — bar
        Top of the pressure axis.
    """

    spots: tuple[float, float]
    contact: tuple[float, float]
    speed_kmh: float
    pressure_bar: float


BAND_ROOM_C = 25.0  # degC: most of a ±1σ band the spot plot's range makes room for
SIGMA_STEP_C = 5.0  # degC: the contact band's 1σ panel tops out at a multiple of this


def time_axis_end(t_max: float) -> float:
    """End of a lap's time axis, s: the lap length rounded up to 10 s."""
    return 10.0 * max(1.0, float(np.ceil(t_max / 10.0 - 1e-9)))


def _rounded_range(
    arrays: tuple[np.ndarray, ...], fallback: tuple[float, float], step: float = 50.0
) -> tuple[float, float]:
    """Range of ``arrays`` out to multiples of ``step``: laps alike share one background."""
    finite = [a[np.isfinite(a)] for a in arrays]
    finite = [a for a in finite if a.size]
    if not finite:
        return fallback
    lo = step * np.floor(min(a.min() for a in finite) / step)
    hi = step * np.ceil(max(a.max() for a in finite) / step)
    return float(lo), float(max(hi, lo + step))


def _figure(height: float) -> Figure:
    fig = plt.figure(figsize=(FIG_WIDTH, height), dpi=DPI)
    fig.subplots_adjust(left=LEFT, right=RIGHT, top=0.86, bottom=0.17)
    return fig


def padded_range(*arrays: np.ndarray, pad: float = 0.06) -> tuple[float, float]:
    """Range of the finite values of ``arrays``, widened by ``pad`` of the span on each side."""
    lo = min((np.nanmin(a) for a in arrays if np.isfinite(a).any()), default=0.0)
    hi = max((np.nanmax(a) for a in arrays if np.isfinite(a).any()), default=1.0)
    span = max(hi - lo, 1.0)
    return lo - pad * span, hi + pad * span


def png_bytes(fig: Figure) -> bytes:
    """The figure as PNG bytes at the report resolution."""
    buf = io.BytesIO()
    # Fast deflate: the PNGs are written once and embedded once; size matters less.
    fig.savefig(buf, format="png", dpi=DPI, pil_kwargs={"compress_level": 1})
    return buf.getvalue()


class _Blitter:
    """One figure drawn as a cached static background plus its animated artists."""

    def __init__(self, fig: Figure):
        self.fig = fig
        self._backgrounds: dict[tuple[float, ...], object] = {}

    def png(self, key: tuple[float, ...], artists: list) -> bytes:
        """Background for ``key`` (drawn once), the ``artists`` over it, as PNG bytes."""
        canvas = self.fig.canvas
        for artist in artists:
            artist.set_animated(True)
        if key not in self._backgrounds:
            canvas.draw()  # animated artists are left out of a full draw
            self._backgrounds[key] = canvas.copy_from_bbox(self.fig.bbox)
        else:
            canvas.restore_region(self._backgrounds[key])
        for artist in artists:
            if artist.get_visible():
                artist.axes.draw_artist(artist)
        width, height = canvas.get_width_height()
        image = Image.frombuffer("RGBA", (width, height), canvas.buffer_rgba(), "raw", "RGBA", 0, 1)
        buf = io.BytesIO()
        image.save(buf, format="png", compress_level=1)
        return buf.getvalue()


class _ZoneMarks:
    """Grey spans over the braking zones and their labels B1, B2... on one axes."""

    def __init__(self, ax: plt.Axes, labels: bool):
        self.spans = PolyCollection(
            [],
            facecolors=ZONE_COLOUR,
            alpha=0.15,
            edgecolors="none",
            transform=ax.get_xaxis_transform(),
            zorder=0,
        )
        ax.add_collection(self.spans, autolim=False)
        self.labels = [
            ax.text(
                0,
                1.01,
                "",
                transform=ax.get_xaxis_transform(),
                ha="center",
                va="bottom",
                fontsize=8,
                color="#555555",
                visible=False,
            )
            for _ in range(MAX_ZONE_LABELS if labels else 0)
        ]

    def update(self, zones_t: np.ndarray, names: tuple[str, ...] = ()) -> None:
        x0, x1 = zones_t[:, 0], zones_t[:, 1]
        verts = np.stack(
            [
                np.column_stack((x0, np.zeros_like(x0))),
                np.column_stack((x1, np.zeros_like(x0))),
                np.column_stack((x1, np.ones_like(x0))),
                np.column_stack((x0, np.ones_like(x0))),
            ],
            axis=1,
        )
        self.spans.set_verts(verts)
        for i, text in enumerate(self.labels):
            text.set_visible(i < len(zones_t))
            if i < len(zones_t):
                text.set_x(0.5 * (x0[i] + x1[i]))
                text.set_text(names[i] if i < len(names) else f"B{i + 1}")


class LapFigures:
    """The four per-lap figures, reused across the laps of a session.

    Parameters
    ----------
    node_radii : ndarray — m
        Radius of each node of the estimate.
    spot_radii : tuple of float — m
        Radii of spot 1..4.
    window_c : (float, float) — degC
        Operating window.
    r_int, r_est : float — m
        Inner and outer radius of the carbon ring (heat-map extent).
    scales : AxisScales
        Session-wide y ranges.
    temp_range_c : (float, float) — degC
        Colour scale of the heat map; one scale for the whole session so that colours
        compare lap to lap.
    measured_spots : tuple of int
        Spots (1..4) the session measures, for the legend.
    """

    def __init__(
        self,
        node_radii: np.ndarray,
        spot_radii: tuple[float, ...],
        window_c: tuple[float, float],
        r_int: float,
        r_est: float,
        scales: AxisScales,
        temp_range_c: tuple[float, float] = (0.0, 1000.0),
        measured_spots: tuple[int, ...] = (3,),
    ):
        self.window_c = window_c
        self.scales = scales
        self.norm = Normalize(vmin=temp_range_c[0], vmax=temp_range_c[1])
        radii = np.asarray(node_radii, dtype=float)
        order = np.argsort(radii)
        self._node_order = order
        self._r_grid = np.linspace(r_int, r_est, HEATMAP_ROWS)
        # Linear interpolation from the (possibly non-uniform) nodes onto the image rows,
        # as one matrix so each lap's heat map is a single product.
        eye = np.eye(radii.size)
        self._interp = np.stack(
            [np.interp(self._r_grid, radii[order], eye[i]) for i in range(radii.size)], axis=1
        )
        self._build_spots(measured_spots)
        self._build_heatmap(spot_radii, r_int, r_est)
        self._build_contact()
        self._build_context()
        self.ax_spots.set_ylim(*scales.spots)
        self.ax_contact.set_ylim(*scales.contact)
        self.ax_speed.set_ylim(0.0, scales.speed_kmh)
        self.ax_pressure.set_ylim(0.0, scales.pressure_bar)
        self._blit = {
            name: _Blitter(fig)
            for name, fig in (
                ("spots", self.fig_spots),
                ("heatmap", self.fig_heatmap),
                ("contact", self.fig_contact),
                ("context", self.fig_context),
            )
        }

    def _build_spots(self, measured_spots: tuple[int, ...]) -> None:
        fig = self.fig_spots = _figure(3.9)
        ax = self.ax_spots = fig.add_subplot()
        self.zone_spots = _ZoneMarks(ax, labels=True)
        self.spot_bands, self.spot_lines, self.meas_lines = [], [], []
        for i, colour in enumerate(SPOT_COLOURS):
            self.spot_bands.append(
                ax.fill_between([0, 1], [0, 0], [0, 0], color=colour, alpha=0.2, linewidth=0)
            )
            (line,) = ax.plot([], [], color=colour, linewidth=1.6, label=f"spot {i + 1} estimate")
            (meas,) = ax.plot(
                [],
                [],
                linestyle="none",
                marker=".",
                markersize=2.5,
                color=colour,
                markeredgecolor="black",
                markeredgewidth=0.2,
                alpha=0.8,
                label=f"spot {i + 1} measured",
            )
            self.spot_lines.append(line)
            self.meas_lines.append(meas)
        ax.set_xlabel("lap time [s]")
        ax.set_ylabel("disc temperature [°C]")
        ax.set_title(
            "Spot temperatures: estimate ±1σ (bands) and IR measurement (dots)", loc="left", pad=14
        )
        measured = [self.meas_lines[i - 1] for i in measured_spots]
        ax.legend(
            handles=self.spot_lines + measured,
            loc="upper left",
            bbox_to_anchor=(1.01, 1.0),
            frameon=False,
            markerscale=4,
        )

    def _build_heatmap(self, spot_radii: tuple[float, ...], r_int: float, r_est: float) -> None:
        fig = self.fig_heatmap = _figure(3.9)
        ax = self.ax_heatmap = fig.add_subplot()
        ax.grid(False)
        self.image = ax.imshow(
            np.zeros((HEATMAP_ROWS, 2)),
            aspect="auto",
            origin="lower",
            cmap="inferno",
            norm=self.norm,
            extent=(0.0, 1.0, r_int * 1e3, r_est * 1e3),
            interpolation="nearest",
        )
        self.spot_marks = []
        for i, r in enumerate(spot_radii):
            self.spot_marks.append(
                ax.axhline(r * 1e3, color=SPOT_COLOURS[i], linestyle="--", linewidth=1.0)
            )
            ax.annotate(
                f"S{i + 1}",
                xy=(1.0, r * 1e3),
                xycoords=("axes fraction", "data"),
                xytext=(3, 0),
                textcoords="offset points",
                va="center",
                color=SPOT_COLOURS[i],
                fontsize=9,
                fontweight="bold",
            )
        self._contours = None
        cax = fig.add_axes((RIGHT + 0.045, 0.17, 0.015, 0.69))
        cbar = fig.colorbar(self.image, cax=cax, extend="both")  # clipped ends are marked
        cbar.set_label("temperature [°C]")
        # Only an edge strictly inside the bar is a visible mark; the title names what is
        # drawn (a bar of 250-760 degC shows neither edge of a 250-850 degC window).
        inside = [e for e in self.window_c if self.norm.vmin < e < self.norm.vmax]
        for edge in inside:
            cax.axhline(edge, color="white", linewidth=1.6)
            cax.axhline(edge, color=WINDOW_COLOUR, linewidth=1.0, linestyle="--")
        ax.set_xlabel("lap time [s]")
        ax.set_ylabel("radius [mm]")
        ax.set_title(
            "Disc temperature across the radius; " + _window_words(self.window_c, inside),
            loc="left",
        )

    def _build_contact(self) -> None:
        fig = self.fig_contact = _figure(4.2)
        fig.subplots_adjust(bottom=0.13, hspace=0.12)
        ax, sig = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": (3.0, 1.0)})
        self.ax_contact, self.ax_sigma = ax, sig
        lo, hi = self.window_c
        ax.axhspan(
            lo, hi, color=WINDOW_COLOUR, alpha=0.12, zorder=0, label=f"window {lo:.0f}–{hi:.0f} °C"
        )
        self.zone_contact = _ZoneMarks(ax, labels=False)
        self.contact_band = ax.fill_between(
            [0, 1], [0, 0], [0, 0], color=CONTACT_COLOUR, alpha=0.25, linewidth=0, label="±1σ"
        )
        (self.contact_line,) = ax.plot(
            [], [], color=CONTACT_COLOUR, linewidth=1.8, label="contact avg"
        )
        ax.set_ylabel("temperature [°C]")
        ax.tick_params(labelbottom=False)
        ax.set_title("Contact-band average (spots 2–4) against the operating window", loc="left")
        # On a 600 °C axis a band of a few degrees is a hairline: its 1σ on its own scale
        # below, so where the estimate is sure and where it is not can be seen.
        (self.sigma_line,) = sig.plot([], [], color=CONTACT_COLOUR, linewidth=1.2)
        sig.set_xlabel("lap time [s]")
        sig.set_ylabel("1σ [°C]")
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
        # The band's size under the legend, drawn per lap (a legend entry would be part of
        # the cached background and keep the first lap's value).
        self._band_label = ax.text(1.02, 0.5, "", transform=ax.transAxes, va="top",
                                   fontsize="small", color="#555555")

    def _build_context(self) -> None:
        fig = self.fig_context = _figure(3.0)
        ax = self.ax_speed = fig.add_subplot()
        self.zone_context = _ZoneMarks(ax, labels=True)
        (self.speed_line,) = ax.plot([], [], color="#333333", linewidth=1.3, label="speed")
        ax.set_xlabel("lap time [s]")
        ax.set_ylabel("speed [km/h]")
        self.ax_pressure = ax.twinx()
        self.ax_pressure.grid(False)
        (self.pressure_line,) = self.ax_pressure.plot(
            [], [], color="#c2185b", linewidth=1.1, label="brake pressure"
        )
        self.ax_pressure.set_ylabel("brake pressure [bar]", color="#c2185b")
        self.ax_pressure.tick_params(axis="y", colors="#c2185b")
        # Axis colours tell the two curves apart; a legend would not fit beside the twin axis.
        ax.set_title(
            "Speed (black) and front brake pressure (red); grey: braking zones", loc="left", pad=14
        )

    def render(self, lap: LapData) -> dict[str, bytes]:
        """Fill the figures with one lap and return each as PNG bytes, keyed by name."""
        t = lap.t
        x_end = time_axis_end(float(t[-1]) if t.size else 0.0)

        for i in range(4):
            lo = lap.spot[i] - lap.spot_std[i]
            hi = lap.spot[i] + lap.spot_std[i]
            self.spot_bands[i].set_data(t, lo, hi)
            self.spot_lines[i].set_data(t, lap.spot[i])
            self.meas_lines[i].set_data(t, lap.measured[i])
        self.zone_spots.update(lap.zones_t, lap.zone_names)
        # From the estimate and the readings, and the bands up to BAND_ROOM_C beyond them: a
        # peak's band stays whole, a wide start-up band stretches the axis by 25 °C at most.
        room = np.minimum(np.nan_to_num(lap.spot_std), BAND_ROOM_C)
        spots_ylim = _rounded_range((lap.spot - room, lap.spot + room, lap.measured),
                                    self.scales.spots)
        self.ax_spots.set_ylim(*spots_ylim)

        field = self._interp @ lap.nodes[self._node_order]
        self.image.set_data(field)
        self.image.set_extent(
            (0.0, float(t[-1]) if t.size > 1 else 0.1, *self.image.get_extent()[2:])
        )
        if self._contours is not None:
            self._contours.remove()
        levels = [v for v in self.window_c if np.nanmin(field) < v < np.nanmax(field)]
        self._contours = None
        if levels and t.size > 1:
            r_mm = self._r_grid * 1e3
            self._contours = self.ax_heatmap.contour(
                t, r_mm, field, levels=levels, colors="white", linewidths=1.0, linestyles="--"
            )

        sigma_top = self._fill_contact(lap)

        self.speed_line.set_data(t, lap.speed_kmh)
        self.pressure_line.set_data(t, lap.pressure_bar)
        self.zone_context.update(lap.zones_t, lap.zone_names)

        for ax in (self.ax_spots, self.ax_heatmap, self.ax_contact, self.ax_speed):
            ax.set_xlim(0.0, x_end)
        contours = [self._contours] if self._contours is not None else []
        return {
            "spots": self._blit["spots"].png(
                (x_end, *spots_ylim),
                [
                    self.zone_spots.spans,
                    *self.spot_bands,
                    *self.spot_lines,
                    *self.meas_lines,
                    *self.zone_spots.labels,
                ],
            ),
            "heatmap": self._blit["heatmap"].png(
                (x_end,), [self.image, *contours, *self.spot_marks]
            ),
            "contact": self._blit["contact"].png(
                (x_end, sigma_top), [self.zone_contact.spans, self.contact_band,
                                     self.contact_line, self._band_label, self.sigma_line]
            ),
            "context": self._blit["context"].png(
                (x_end,),
                [
                    self.zone_context.spans,
                    self.speed_line,
                    self.pressure_line,
                    *self.zone_context.labels,
                ],
            ),
        }

    def _fill_contact(self, lap: LapData) -> float:
        """The contact plot and its σ panel for one lap; returns the panel's top, degC."""
        t = lap.t
        self.contact_band.set_data(t, lap.contact - lap.contact_std, lap.contact + lap.contact_std)
        # On a 600 °C axis a band of a few degrees is a hairline: the legend gives its size
        # (the lap's median σ), the panel below its course through the lap.
        std = lap.contact_std[np.isfinite(lap.contact_std)]
        self._band_label.set_text(f"σ ≈ {np.median(std):.1f} °C (median)" if std.size else "")
        self.contact_line.set_data(t, lap.contact)
        self.sigma_line.set_data(t, lap.contact_std)
        # 5 % headroom keeps the peak off the frame; the start-up prior (tens of degrees)
        # would flatten the rest of the first lap, so the panel stops at BAND_ROOM_C
        peak = 1.05 * np.max(std, initial=0.0)
        sigma_top = SIGMA_STEP_C * min(max(1.0, np.ceil(peak / SIGMA_STEP_C)),
                                       BAND_ROOM_C / SIGMA_STEP_C)
        self.ax_sigma.set_ylim(0.0, sigma_top)
        self.zone_contact.update(lap.zones_t, lap.zone_names)
        return float(sigma_top)

    def close(self) -> None:
        """Release the figures."""
        for fig in (self.fig_spots, self.fig_heatmap, self.fig_contact, self.fig_context):
            plt.close(fig)


def trend_figure(
    laps: np.ndarray,
    peak_spot: np.ndarray,
    mean_contact: np.ndarray,
    inside_pct: np.ndarray,
    window_c: tuple[float, float],
) -> bytes:
    """Lap-by-lap trend of a session as PNG bytes.

    Parameters
    ----------
    laps : ndarray of int
        Lap numbers.
    peak_spot : ndarray, shape (4, n_laps) — degC
        Peak estimated temperature of each spot per lap.
    mean_contact : ndarray — degC
        Mean contact-band temperature per lap.
    inside_pct : ndarray — %
        Share of the lap the contact band spent inside the window.
    window_c : (float, float) — degC
    """
    fig = plt.figure(figsize=(FIG_WIDTH, 5.6), dpi=DPI)
    ax_t, ax_w = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2.2, 1]})
    fig.subplots_adjust(left=LEFT, right=RIGHT, top=0.93, bottom=0.1, hspace=0.12)
    lo, hi = window_c
    ax_t.axhspan(
        lo, hi, color=WINDOW_COLOUR, alpha=0.12, zorder=0, label=f"window {lo:.0f}–{hi:.0f} °C"
    )
    for i, colour in enumerate(SPOT_COLOURS):
        ax_t.plot(
            laps, peak_spot[i], marker="o", markersize=4, color=colour, label=f"peak spot {i + 1}"
        )
    ax_t.plot(
        laps,
        mean_contact,
        marker="s",
        markersize=4,
        color=CONTACT_COLOUR,
        linestyle="--",
        label="mean contact band",
    )
    ax_t.set_ylabel("temperature [°C]")
    ax_t.set_title(
        "Lap by lap: peak spot temperatures and mean contact-band temperature", loc="left"
    )
    ax_t.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    ax_w.bar(laps, inside_pct, color=WINDOW_COLOUR, alpha=0.8, width=0.7)
    ax_w.set_ylim(0, 100)
    ax_w.set_ylabel("in window [%]")
    ax_w.set_xlabel("lap")
    ax_w.set_xticks(laps)
    png = png_bytes(fig)
    plt.close(fig)
    return png


def _window_words(window_c: tuple[float, float], inside: list[float]) -> str:
    """What the heat map shows of the window: white dashed contours where a lap crosses an
    edge, and the edges marked on its colour bar (those inside the bar's range)."""
    lo, hi = window_c
    words = f"window {lo:.0f}–{hi:.0f} °C white dashed where crossed"
    if not inside:
        return words + "; both edges beyond the colour bar"
    if len(inside) == 1:
        return words + f"; {inside[0]:.0f} °C marked on the colour bar"
    return words + "; both edges marked on the colour bar"
