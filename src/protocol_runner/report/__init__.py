"""The HTML report, regenerated from an archive alone (docs/report.md): `load.load_report_data` reads the
archive into `model.ReportData`, `render.generate_report` writes the page (figures: `figures.py`).

Kept free of imports so that `protocol_runner.report.load` does not pull in matplotlib.
"""
