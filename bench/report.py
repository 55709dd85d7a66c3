"""The demo's report: one static HTML page (no server, opens from disk) with each part's printed table and its
figures, written atomically into the report folder beside the figures."""

from __future__ import annotations

import html
from dataclasses import dataclass, field
from pathlib import Path

from core.files import write_text

TITLE = "dcfvision demo"
STYLE = ("body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}"
         "pre{background:#f4f4f4;padding:.8em;overflow-x:auto;font-size:12px}"
         "figure{margin:1em 0}img{max-width:100%;border:1px solid #ddd}figcaption{font-size:13px;color:#555}"
         "h2{border-bottom:1px solid #ccc;padding-bottom:.2em}")


@dataclass
class DemoPart:
    """One capability's part of the demo: what it printed, how long it took, its figures (file, caption)."""

    name: str
    title: str
    seconds: float
    text: str
    figures: list[tuple[str, str]] = field(default_factory=list)


def report_html(parts: list[DemoPart], total_seconds: float) -> str:
    """The report page of ``parts`` (well-formed XHTML: every element closed, all text escaped)."""
    rows = "".join(f"<li><a href=\"#{p.name}\">{html.escape(p.title)}</a> ({p.seconds:.0f} s)</li>" for p in parts)
    sections = []
    for p in parts:
        text = html.escape(p.text.strip("\n"))  # keep the tables' leading spaces
        figures = "".join(f"<figure><img src=\"{html.escape(f)}\" alt=\"{html.escape(c)}\"/>"
                          f"<figcaption>{html.escape(c)}</figcaption></figure>" for f, c in p.figures)
        sections.append(f"<section id=\"{p.name}\"><h2>{html.escape(p.title)}</h2>"
                        f"<p>{p.seconds:.0f} s on this machine.</p><pre>{text}</pre>"
                        f"{figures}</section>")
    return (f"<!DOCTYPE html>\n<html xmlns=\"http://www.w3.org/1999/xhtml\" lang=\"en\"><head><meta charset=\"utf-8\"/>"
            f"<title>{TITLE}</title><style>{STYLE}</style></head><body><h1>{TITLE}</h1>"
            f"<p>Every capability on the project's own synthetic data (and the shared reconstruction when present), "
            f"{total_seconds:.0f} s in all.</p><ul>{rows}</ul>{''.join(sections)}</body></html>\n")


def write_report(out_dir: Path, parts: list[DemoPart], total_seconds: float) -> Path:
    """Write ``out_dir/index.html`` (atomically, after the figures); returns its path."""
    return write_text(Path(out_dir) / "index.html", report_html(parts, total_seconds))
