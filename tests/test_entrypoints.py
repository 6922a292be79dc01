"""The entry-point cache answers what importlib.metadata answers, and notices installs."""

import json
import os
from importlib import metadata

import pytest

from parsel_core import entrypoints
from parsel_core.entrypoints import InstalledEntryPoint, cache_dir, installed_entry_points

GROUPS = ("parsel", "parsel.commands", "console_scripts")


def expected(group: str) -> list[tuple]:
    return sorted(((ep.name, ep.value, ep.dist.name if ep.dist else None, ep.dist.version if ep.dist else None)
                   for ep in metadata.entry_points(group=group)), key=lambda row: row[0])


def rows(found: list[InstalledEntryPoint]) -> list[tuple]:
    return [(ep.name, ep.value, ep.distribution, ep.version) for ep in found]


def install(site, name: str, version: str, entry_points: str):
    """A distribution as pip leaves it: ``name-version.dist-info`` with metadata."""
    info = site / f"{name}-{version}.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n")
    (info / "entry_points.txt").write_text(entry_points)
    return info


def never_read(groups):
    raise AssertionError("read the installed metadata on a cache hit")


def test_the_answer_is_importlib_metadata_s_from_cold_and_warm(tmp_path, monkeypatch):
    cold = installed_entry_points(GROUPS, tmp_path)
    assert [path.name for path in tmp_path.iterdir()][0].startswith("entry-points-")
    monkeypatch.setattr(entrypoints, "_read_installed", never_read)
    warm = installed_entry_points(GROUPS, tmp_path)
    assert cold == warm
    for group in GROUPS:
        assert rows(warm[group]) == expected(group), group
    assert {ep.name for ep in warm["parsel"]} >= {"aep", "mesh", "offline", "relations"}


def test_loading_gives_the_object_importlib_metadata_loads():
    found = installed_entry_points(["parsel"], None)["parsel"]
    for ep in metadata.entry_points(group="parsel"):
        ours = next(e for e in found if e.name == ep.name)
        assert ours.load() is ep.load()
    assert InstalledEntryPoint("j", "os.path : join [extra]", "g", None, None).load() is os.path.join
    assert InstalledEntryPoint("m", "json", "g", None, None).load() is json


def test_installing_editing_and_removing_a_distribution_is_seen(tmp_path, monkeypatch):
    site, cache = tmp_path / "site", tmp_path / "cache"
    site.mkdir()
    monkeypatch.syspath_prepend(str(site))
    group = ["parsel.cache-test"]
    assert installed_entry_points(group, cache)[group[0]] == []
    info = install(site, "demo_plugin", "1.0", "[parsel.cache-test]\ndemo = demo_plugin:hooks\n")
    assert rows(installed_entry_points(group, cache)[group[0]]) == [("demo", "demo_plugin:hooks", "demo_plugin", "1.0")]

    # an edit in place: same folder, same size, a later modification time
    text = (info / "entry_points.txt")
    text.write_text("[parsel.cache-test]\ndemo = demo_plugin:other\n")
    stat = text.stat()
    os.utime(text, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000_000))
    assert rows(installed_entry_points(group, cache)[group[0]]) == [("demo", "demo_plugin:other", "demo_plugin", "1.0")]

    # on a file system with coarse times: the same time, another size
    stat = text.stat()
    text.write_text("[parsel.cache-test]\ndemo = demo_plugin:others\n")
    os.utime(text, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert rows(installed_entry_points(group, cache)[group[0]])[0][1] == "demo_plugin:others"

    # an upgrade, as pip does it: the old folder removed, the new one written
    for item in info.iterdir():
        item.unlink()
    info.rmdir()
    install(site, "demo_plugin", "2.0", "[parsel.cache-test]\ndemo = demo_plugin:hooks\n")
    assert rows(installed_entry_points(group, cache)[group[0]]) == [("demo", "demo_plugin:hooks", "demo_plugin", "2.0")]

    # and the answer is not read again while nothing changes
    monkeypatch.setattr(entrypoints, "_read_installed", never_read)
    assert rows(installed_entry_points(group, cache)[group[0]])[0][3] == "2.0"


def test_a_damaged_cache_file_is_read_again_and_rewritten(tmp_path):
    first = installed_entry_points(GROUPS, tmp_path)
    (file,) = tmp_path.glob("entry-points-*.json")
    for damage in ("{not json", json.dumps({"format": 1}), json.dumps([1, 2]), "",
                   json.dumps({"format": entrypoints.FORMAT, "fingerprint": "x", "groups": {}})):
        file.write_text(damage)
        assert installed_entry_points(GROUPS, tmp_path) == first
        assert json.loads(file.read_text())["groups"]["parsel"]


def test_a_cache_folder_that_cannot_be_written_is_no_error(tmp_path):
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    assert installed_entry_points(GROUPS, blocked / "cache") == installed_entry_points(GROUPS, None)
    assert blocked.read_text() == "not a folder"


def test_the_cache_folder_comes_from_the_environment(tmp_path):
    assert cache_dir({"PARSEL_CACHE_DIR": str(tmp_path)}) == tmp_path
    assert cache_dir({"PARSEL_CACHE_DIR": ""}) is None
    assert cache_dir({"XDG_CACHE_HOME": str(tmp_path)}) == tmp_path / "parsel"
    assert cache_dir({}) == entrypoints.Path(os.path.expanduser("~")) / ".cache" / "parsel"


def test_the_cache_turned_off_writes_nothing(tmp_path, monkeypatch):
    monkeypatch.setenv("PARSEL_CACHE_DIR", "")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setenv("HOME", str(tmp_path))
    assert rows(installed_entry_points(["parsel"])["parsel"]) == expected("parsel")
    assert not list(tmp_path.rglob("*"))


@pytest.mark.parametrize("path", [["/nowhere/at/all"], ["", "/nowhere"]])
def test_the_fingerprint_takes_missing_folders_and_the_working_directory(path, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    before = entrypoints.fingerprint(path)
    assert json.loads(json.dumps(before)) == before
    (tmp_path / "x-1.dist-info").mkdir()
    assert (entrypoints.fingerprint(path) != before) == ("" in path)
