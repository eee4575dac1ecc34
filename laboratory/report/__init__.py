"""The run's report: one self-contained HTML file (report.html) rendered from the record in
a run directory alone (run.json, the results JSON, sheets/*.json, the PNGs), never from live
state; Jinja2 templates in ``templates/``, images inline as data: URIs, a print stylesheet.
"""

from laboratory.report.html import (
    REPORT_NAME,
    ReportError,
    prepare_report,
    render_history_page,
    render_report,
    report_after,
    write_report,
)

__all__ = ["REPORT_NAME", "ReportError", "prepare_report", "render_history_page", "render_report",
           "report_after", "write_report"]
