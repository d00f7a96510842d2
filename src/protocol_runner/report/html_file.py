"""The report's HTML pages as files: the template environment, the output path's checks and the atomic write
(shared by the session report, `render.py`, and the comparison page, `compare.py`)."""

from __future__ import annotations

import os
from pathlib import Path

import jinja2

from protocol_runner.archive.outputs import create_new, refuse_special, temporary_beside
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
    """`output` as a Path, or InvalidInput when it is a directory, exists and is not a regular file (a
    symbolic link, a device, a FIFO: archive/outputs.py), or its folder does not exist (`page` names the
    page in the message, `example` is a file name to suggest)."""
    output = Path(output)
    if output.is_dir() and not output.is_symlink():
        raise InvalidInput(f"{page} output {output} is a directory; give a file name such as {example}.")
    refuse_special(output, f"{page} output")
    if not output.parent.is_dir():
        raise InvalidInput(f"{page} output directory {output.parent} does not exist.")
    return output


def write_atomically(output: Path, text: str) -> None:
    """Write `text` to `output` through a temporary file and a rename: a reader never sees half a page.

    A path that is not valid UTF-8 (a session directory named with a byte of another encoding) shows in the
    page with U+FFFD where that byte was: the page itself is always valid UTF-8."""
    refuse_special(output, "output")  # checked again just before the write: never replaced by a rename
    page = text.encode("utf-8", "surrogateescape").decode("utf-8", "replace")
    tmp = temporary_beside(output)
    try:
        with create_new(tmp) as fh:
            fh.write(page)
        os.replace(tmp, output)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
