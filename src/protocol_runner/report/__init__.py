"""The HTML report, regenerated from an archive alone (docs/report.md). Kept free of imports so that
`protocol_runner.report.load` does not pull in matplotlib."""
