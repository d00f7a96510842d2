"""`python -m protocol_runner ...`: the `run-protocol` command, for an environment whose scripts directory
is not on the PATH."""

from protocol_runner.cli import entry

if __name__ == "__main__":
    entry()
