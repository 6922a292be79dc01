"""File helpers: JSON reads fail with one line naming the file; writes are atomic."""

from __future__ import annotations

import pytest

from parsel_core.errors import ParselError
from parsel_core.io import atomic_write_text, read_json


def test_read_json_returns_the_document(tmp_path):
    path = tmp_path / "shape.json"
    path.write_text('{"parts": [1, 2]}', encoding="utf-8")
    assert read_json(path) == {"parts": [1, 2]}


@pytest.mark.parametrize(("content", "what", "message"), [
    (None, "", "missing.json: cannot read: No such file or directory"),
    (None, "labels", "missing.json: cannot read labels: No such file or directory"),
    (b'{"a": ', "", "missing.json: not valid JSON: Expecting value"),
    (b'{"a": ', "labels", "missing.json: labels file is not valid JSON: Expecting value"),
    (b"\xff\xfe{}", "", "missing.json: not valid JSON: 'utf-8' codec can't decode"),
])
def test_read_json_errors_name_the_file_in_one_line(tmp_path, content, what, message):
    path = tmp_path / "missing.json"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(ParselError) as caught:
        read_json(path, what)
    text = str(caught.value)
    assert text.startswith(str(tmp_path)) and message in text and "\n" not in text


def test_atomic_write_replaces_whole_files_only(tmp_path):
    path = tmp_path / "out.txt"
    atomic_write_text(path, "first")
    atomic_write_text(path, "second")
    assert path.read_text() == "second"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]  # no temporary file left
    with pytest.raises(ParselError):
        atomic_write_text(tmp_path / "no-such-dir" / "out.txt", "x")
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_read_json_refuses_unusable_documents_in_one_line(tmp_path):
    path = tmp_path / "deep.json"
    path.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(ParselError, match="deep.json: not usable JSON") as caught:
        read_json(path)
    assert "\n" not in str(caught.value)
