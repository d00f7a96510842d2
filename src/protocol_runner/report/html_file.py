"""The report's HTML pages as files: the template environment, the output path's checks and the atomic write
(shared by the session report, `render.py`, and the comparison page, `compare.py`)."""

from __future__ import annotations

import os
from pathlib import Path

import jinja2

from protocol_runner.errors import InvalidInput
from protocol_runner.resources import templates_dir


def template_environment(*, keep_trailing_newline: bool = False) -> jinja2.Environment:
    """The package's templates: HTML-escaped, every variable required, block tags without stray lines."""
    return jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(templates_dir())),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=keep_trailing_newline,
    )


def checked_output(output: Path, page: str, example: str) -> Path:
    """`output` as a Path, or InvalidInput when it is a directory or its folder does not exist
    (`page` names the page in the message, `example` is a file name to suggest)."""
    output = Path(output)
    if output.is_dir():
        raise InvalidInput(f"{page} output {output} is a directory; give a file name such as {example}.")
    if not output.parent.is_dir():
        raise InvalidInput(f"{page} output directory {output.parent} does not exist.")
    return output


def write_atomically(output: Path, text: str) -> None:
    """Write `text` to `output` through a temporary file and a rename: a reader never sees half a page."""
    # a plain open() so the file gets the usual permissions (umask), unlike mkstemp's 0600
    tmp = output.with_name(f".{output.name}.{os.getpid()}.partial")
    try:
        with tmp.open("w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, output)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
