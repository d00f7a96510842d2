"""The HTML report, regenerated from an archive alone (docs/report.md).

    model.py     ReportData: frozen dataclasses holding everything the report shows
    load.py      load_report_data(path) (checked by archive/verify.py)
    evaluate.py  evaluate_expectations(data): the protocol's expectations decided on the data
    declared.py  declared_citations(text), ...: what the archived protocol declares for the report
    figures.py   draw_here(data, ids, workers): matplotlib (Agg) figures as PNG data URIs
    parallel.py  map_in_processes(...): worker processes with a serial fallback
    render.py    generate_report(archive, output=None), render_report(data, output): jinja2 -> one HTML file

Kept free of imports so that `protocol_runner.report.load` does not pull in matplotlib.
"""
