"""The HTML report, regenerated from an archive alone (docs/report.md).

    model.py     ReportData: frozen dataclasses holding everything the report shows
    load.py      load_report_data(path), validate_archive(path), load_reference_dataset(path)
    findings.py  evaluate_findings(data): the thesis's Chapter 5 findings checked against the data
    figures.py   render_figures(data): matplotlib (Agg) figures as PNG data URIs
    parallel.py  map_in_processes(...): forked workers with a serial fallback
    render.py    generate_report(archive, output=None), render_report(data, output): jinja2 -> one HTML file

Kept free of imports so that `protocol_runner.report.load` does not pull in matplotlib.
"""
