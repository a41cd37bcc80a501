"""A generic report page: cards, sections of text, tables and figures, one HTML file.

The per-lap disc reports have their own layout (:mod:`brakethermo.report.lap_report`);
every other command (diagnose, the rig pipelines) describes its page with
:class:`Page` and writes it with :func:`write_page`: the PNGs beside ``index.html``,
the HTML referencing them by relative path, so the folder can be copied or served as
a whole. Every string is escaped by Jinja's autoescaping: text from a file never
becomes markup.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
from jinja2 import Environment, PackageLoader, select_autoescape
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from brakethermo.io.atomic import write_bytes_atomic, write_text_atomic
from brakethermo.report.figures import png_bytes


@dataclass(frozen=True)
class Card:
    """A headline figure: ``label``, ``value`` (already formatted) and its ``unit``."""

    label: str
    value: str
    unit: str = ""


@dataclass(frozen=True)
class TableBlock:
    """A table: ``header`` cells and ``rows`` of already formatted cells."""

    header: Sequence[str]
    rows: Sequence[Sequence[object]]
    caption: str = ""


@dataclass
class Section:
    """A titled part of the page.

    Attributes
    ----------
    heading : str
    paragraphs : list of str
        Running text, shown before the tables.
    tables : list of TableBlock
    figures : dict of str to Figure
        PNG file stem -> matplotlib figure; each becomes ``<stem>.png`` beside the page.
    notes : list of str
        Small print under the figures (assumptions, what was not measured).
    links : list of (str, str)
        (text, relative href) of other pages, listed after the paragraphs.
    """

    heading: str
    paragraphs: list[str] = field(default_factory=list)
    tables: list[TableBlock] = field(default_factory=list)
    figures: dict[str, Figure] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    links: list[tuple[str, str]] = field(default_factory=list)


@dataclass
class Page:
    """A whole report page."""

    title: str
    subtitle: str = ""
    cards: list[Card] = field(default_factory=list)
    sections: list[Section] = field(default_factory=list)
    footer: str = ""
    back_href: str | None = None
    #: a session folder's own page: a list of the pages other commands wrote beside it
    #: (``report.session_links``) is kept in it
    sibling_pages: bool = False


def as_number(x: Any) -> float:
    """A value for a page as a float: NaN when it is missing (None, a JSON null once the
    summary has been through summary.json) or not a number."""
    try:
        return float(x)
    except (TypeError, ValueError):
        return float("nan")


def number_text(x: Any, spec: str = ".1f") -> str:
    """``x`` formatted by ``spec`` (Python's format mini-language); '–' when it is missing
    or not finite."""
    v = as_number(x)
    return format(v, spec) if math.isfinite(v) else "–"


def template_environment(**options: bool) -> Environment:
    """The Jinja environment of the report templates, HTML autoescaping on."""
    return Environment(
        loader=PackageLoader("brakethermo.report", "templates"),
        autoescape=select_autoescape(["html", "j2"]),
        **options,
    )


def write_page(page: Page, folder: Path, name: str = "index.html") -> Path:
    """Write the page's PNGs and ``folder/name``; each file atomically.

    Parameters
    ----------
    page : Page
    folder : Path
        Destination folder (created if needed).
    name : str
        HTML file name.

    Returns
    -------
    Path
        The HTML file.
    """
    folder.mkdir(parents=True, exist_ok=True)
    sections = []
    for section in page.sections:
        figures = []
        for stem, fig in section.figures.items():
            write_bytes_atomic(folder / f"{stem}.png", png_bytes(fig))
            plt.close(fig)
            figures.append({"src": f"{stem}.png", "alt": f"{section.heading}: {stem}"})
        sections.append({
            "heading": section.heading,
            "paragraphs": section.paragraphs,
            "tables": section.tables,
            "figures": figures,
            "notes": section.notes,
            "links": section.links,
        })
    env = template_environment(trim_blocks=True, lstrip_blocks=True)
    html = env.get_template("page.html.j2").render(
        page={
            "title": page.title,
            "subtitle": page.subtitle,
            "cards": page.cards,
            "sections": sections,
            "footer": page.footer,
            "back_href": page.back_href,
            "sibling_pages": page.sibling_pages,
        }
    )
    target = folder / name
    write_text_atomic(target, html)
    return target


def finish_figure(fig: Figure, ax: Axes, xlabel: str, ylabel: str, **legend: Any) -> Figure:
    """Label ``ax``, give it the pages' light grid and small legend (``legend`` adds to or
    overrides ``fontsize=8``), tighten ``fig``'s layout; return ``fig``."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    ax.legend(**{"fontsize": 8, **legend})
    fig.tight_layout()
    return fig


def consistency_text(c: dict[str, Any]) -> str:
    """A filter's NIS check in one phrase (``estimation.consistency.nis_consistency``)."""
    if not c or not c.get("n"):
        return "no measurements to check it on"
    lo, hi = c["chi2_band"]
    figures = (f"mean NIS {c['mean_nis']:.2f} per step (95 % band {lo:.2f}–{hi:.2f} for"
               f" {c['dof_per_step']:g} measured value(s) a step)")
    if c.get("structured"):  # the band's assumption fails: "under-confident" would mislead
        return (f"strongly autocorrelated innovations (lag 1 {c['lag1_autocorrelation']:+.2f},"
                " where independent ones read about 0): the model's shape leaves a"
                " structured error that the filter follows step by step, so its band does"
                f" not hold, whatever the NIS says ({figures}: {c['state']} by the NIS"
                " alone)")
    return (f"mean NIS {c['mean_nis']:.2f} per step, {c['state']} (95 % band"
            f" {lo:.2f}–{hi:.2f} for {c['dof_per_step']:g} measured value(s) a step;"
            f" lag-1 autocorrelation of the innovations {c['lag1_autocorrelation']:+.2f})")


def verdict_text(summary: dict[str, Any]) -> str:
    """A diagnosis.json's verdict in words: the name, or a set as "one of a / b (why)" with
    the clause that made it a set (``verdict_why``; a file of an older run has none)."""
    if summary.get("verdict_kind") != "set":
        return str(summary["verdict"])
    why = summary.get("verdict_why") or "the data cannot tell them apart"
    return "one of " + " / ".join(summary["verdict_set"]) + f" ({why})"
