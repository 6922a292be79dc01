"""The entry-point cache answers what importlib.metadata answers, and notices installs."""

import importlib
import json
import os
import sys
from importlib import metadata
from pathlib import Path

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
    importlib.invalidate_caches()  # (importlib.metadata keeps folder listings by their time)
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
    importlib.invalidate_caches()
    stat = text.stat()
    os.utime(text, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000_000))
    assert rows(installed_entry_points(group, cache)[group[0]]) == [("demo", "demo_plugin:other", "demo_plugin", "1.0")]

    # on a file system with coarse times: the same time, another size
    stat = text.stat()
    text.write_text("[parsel.cache-test]\ndemo = demo_plugin:others\n")
    importlib.invalidate_caches()
    os.utime(text, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert rows(installed_entry_points(group, cache)[group[0]])[0][1] == "demo_plugin:others"

    # an upgrade, as pip does it: the old folder removed, the new one written
    for item in info.iterdir():
        item.unlink()
    info.rmdir()
    importlib.invalidate_caches()
    install(site, "demo_plugin", "2.0", "[parsel.cache-test]\ndemo = demo_plugin:hooks\n")
    assert rows(installed_entry_points(group, cache)[group[0]]) == [("demo", "demo_plugin:hooks", "demo_plugin", "2.0")]

    # and the answer is not read again while nothing changes
    monkeypatch.setattr(entrypoints, "_read_installed", never_read)
    assert rows(installed_entry_points(group, cache)[group[0]])[0][3] == "2.0"


def test_a_damaged_cache_file_is_read_again_and_rewritten(tmp_path):
    first = installed_entry_points(GROUPS, tmp_path)
    (file,) = tmp_path.glob("entry-points-*.json")
    good = json.loads(file.read_text())
    (key, stored), = good["entries"]

    def with_groups(groups):
        return json.dumps({**good, "entries": [[key, groups]]})

    damaged = ["{not json", "", "[1, 2]", json.dumps({"format": 1}), "[" * 100_000,
               json.dumps({**good, "entries": {"a": 1}}), json.dumps({**good, "entries": [[key]]}),
               json.dumps({**good, "entries": [["another path", stored]]}),
               # the right fingerprint, rows of the wrong shape
               with_groups([]), with_groups({**stored, "parsel": "abcd"}),
               with_groups({**stored, "parsel": [[1, "x", None, None]]}),
               with_groups({**stored, "parsel": [["a", "x", None]]}),
               with_groups({**stored, "parsel": [["a", ["x"], None, None]]}),
               with_groups({g: rows for g, rows in stored.items() if g != "parsel"})]
    for damage in damaged:
        file.write_text(damage)
        assert installed_entry_points(GROUPS, tmp_path) == first, damage[:80]
        assert json.loads(file.read_text())["entries"][0] == [key, stored]


def test_unusual_import_path_entries_are_read_as_importlib_reads_them(tmp_path, monkeypatch):
    odd = os.fsdecode(bytes(tmp_path) + b"/\xff-not-utf-8")
    monkeypatch.setattr(sys, "path", [Path(tmp_path), odd, *sys.path])
    for _ in ("cold", "warm"):
        assert rows(installed_entry_points(["parsel"], tmp_path / "cache")["parsel"]) == expected("parsel")


def test_the_file_keeps_the_last_import_paths(tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    for i in range(entrypoints.KEPT + 3):
        monkeypatch.syspath_prepend(str(tmp_path / f"path-{i}"))
        installed_entry_points(["parsel"], cache)
    (file,) = cache.glob("entry-points-*.json")
    entries = json.loads(file.read_text())["entries"]
    assert len(entries) == entrypoints.KEPT
    assert entries[0][0] == entrypoints.fingerprint(entrypoints.import_path())


def test_an_egg_on_the_import_path_is_watched(tmp_path, monkeypatch):
    egg = tmp_path / "demo_egg-1.0-py3.11.egg"
    (egg / "EGG-INFO").mkdir(parents=True)
    (egg / "EGG-INFO" / "PKG-INFO").write_text("Metadata-Version: 1.1\nName: demo_egg\nVersion: 1.0\n")
    text = egg / "EGG-INFO" / "entry_points.txt"
    text.write_text("[parsel.cache-test]\na = demo_egg:a\n")
    monkeypatch.syspath_prepend(str(egg))
    group, cache = ["parsel.cache-test"], tmp_path / "cache"
    assert [e.name for e in installed_entry_points(group, cache)[group[0]]] == ["a"]
    text.write_text("[parsel.cache-test]\na = demo_egg:a\nb = demo_egg:b\n")
    importlib.invalidate_caches()
    assert [e.name for e in installed_entry_points(group, cache)[group[0]]] == ["a", "b"]
    assert rows(installed_entry_points(group, cache)[group[0]]) == expected(group[0])


def test_a_cache_folder_that_cannot_be_written_is_no_error(tmp_path):
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    assert installed_entry_points(GROUPS, blocked / "cache") == installed_entry_points(GROUPS, None)
    assert blocked.read_text() == "not a folder"


def test_the_cache_folder_comes_from_the_environment(tmp_path):
    assert cache_dir({"PARSEL_CACHE_DIR": str(tmp_path)}) == tmp_path
    assert cache_dir({"PARSEL_CACHE_DIR": ""}) is None
    assert cache_dir({"XDG_CACHE_HOME": str(tmp_path)}) == tmp_path / "parsel"
    home = Path(os.path.expanduser("~")) / ".cache" / "parsel"
    assert cache_dir({}) == home
    assert cache_dir({"XDG_CACHE_HOME": "relative/cache"}) == home  # (relative: ignored, as XDG asks)
    assert cache_dir({"PARSEL_CACHE_DIR": "~/elsewhere"}) == Path(os.path.expanduser("~/elsewhere"))


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
