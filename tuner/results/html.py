"""HTML building blocks of the reports: escaping, numbers that carry their value, tables, figures, the page
(style, numbered sections), model labels and colours."""
from __future__ import annotations

import html
import re
from pathlib import Path

from damper_fmu.parameters import MODEL_KINDS


__all__ = ["MODEL_ORDER", "MODEL_LABEL", "MODEL_COLOR", "num", "model_label", "esc", "safe_name", "table", "figure_html", "NOT_DRAWN", "write_page"]

MODEL_ORDER = MODEL_KINDS
MODEL_LABEL = {"lumped": "lumped (proposed)", "maxwell": "Maxwell (linear)",
               "maxwell_table": "Maxwell, table dashpot", "twochamber": "two-chamber (twin-tube form)"}
MODEL_COLOR = {"lumped": "tab:green", "maxwell": "tab:red", "maxwell_table": "tab:orange", "twochamber": "tab:purple"}
def num(value, text: str) -> str:
    """HTML span showing ``text`` and carrying the exact value (machine-readable)."""
    return f'<span class="num" data-value="{float(value)!r}">{html.escape(text)}</span>'


def model_label(m: str) -> str:
    """HTML label of a model: readable name and the key used in the output files."""
    return f"{html.escape(MODEL_LABEL.get(m, m))} [<code>{html.escape(m)}</code>]"


def esc(s) -> str:
    return html.escape(str(s))


def safe_name(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or "test"


def table(header: list[str], rows: list[list[str]], cls: str = "", row_classes=None) -> str:
    """HTML table; header cells are escaped, body cells are trusted HTML."""
    out = [f'<table class="{cls}"><thead><tr>' + "".join(f"<th>{esc(h)}</th>" for h in header)
           + "</tr></thead><tbody>"]
    for i, r in enumerate(rows):
        c = f' class="{row_classes[i]}"' if row_classes and row_classes[i] else ""
        out.append(f"<tr{c}>" + "".join(f"<td>{cell}</td>" for cell in r) + "</tr>")
    out.append("</tbody></table>")
    return "\n".join(out)


class _NotDrawn:
    """The ``src`` of a figure a report was written without (``make_report(figures=False)``)."""

    def __repr__(self) -> str:
        return "NOT_DRAWN"


#: ``figure_html``'s ``src`` for a figure not drawn: the report was written without figures
NOT_DRAWN = _NotDrawn()


def figure_html(src, caption: str, missing: str) -> str:
    """A figure with its caption; ``src`` None: the note that it was skipped and why (``missing``); ``NOT_DRAWN``:
    the caption with the note that the report was written without figures and how to draw them."""
    if src is NOT_DRAWN:
        return (f'<p class="skip">Figure not drawn (this report was written without figures; '
                f'<code>python -m tuner report FOLDER</code> draws them): {caption}</p>')
    if src is None:
        return f'<p class="skip">Figure skipped: {esc(missing)}</p>'
    return (f'<figure><a href="{esc(src)}"><img src="{esc(src)}" alt="{esc(caption)}"></a>'
            f"<figcaption>{caption}</figcaption></figure>")


_CSS = """
body{font-family:system-ui,Segoe UI,Helvetica,Arial,sans-serif;max-width:1100px;margin:auto;padding:1em;color:#222}
h1{font-size:1.6em}h2{border-bottom:1px solid #ccc;margin-top:1.8em}
table{border-collapse:collapse;margin:0.6em 0;font-size:0.88em}
th,td{border:1px solid #ccc;padding:3px 7px;text-align:right;vertical-align:top}
th{background:#f0f0f0}td:first-child,td:nth-child(2){text-align:left}
tr.ident{background:#f4f4f4;color:#555}tr.flagged{background:#fff1d6}.flag{color:#b35900;font-weight:bold}
figure{margin:1em 0}img{max-width:100%;border:1px solid #ddd}figcaption{font-size:0.9em;color:#444}
.skip{color:#8a5a00;font-style:italic}.verdict{background:#eef6ee;padding:0.6em;border-left:4px solid #3a3}
pre{white-space:pre-wrap;margin:0;font-size:0.9em}.eq{font-family:monospace}
table.settings td{text-align:left}
"""


def _number_sections(html_text: str) -> str:
    """Number the ``<h2>`` section headings 1, 2, ... in the order they appear (whatever sections a
    run has), replacing any number they carry."""
    count = iter(range(1, 1000))
    return re.sub(r"<h2>(?:\d+\.\s*)?", lambda m: f"<h2>{next(count)}. ", html_text)


def write_page(out: Path, title: str, body: list[str]) -> Path:
    page = (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>{title}</title>"
            f"<style>{_CSS}</style></head><body>" + _number_sections("\n".join(body)) + "</body></html>\n")
    path = out / "report.html"
    path.write_text(page, encoding="utf-8")
    return path
