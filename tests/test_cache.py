"""The content-addressed cache: found again, never trusted when corrupt or from another version."""

import json

import pytest

from dfwb.studies import cache as cache_module
from dfwb.studies.cache import Cache, NoCache, default_dir

KEY = {"kind": "df", "F": 10.0, "omega": 1.0, "params": {"M": 1.0}}
VALUE = {"N_re": -0.25, "N_im": -0.3, "harmonics": [0.0, 0.1]}


def test_a_stored_value_is_found_by_an_equal_key_in_any_order(tmp_path):
    cache = Cache(tmp_path)
    cache.put(KEY, VALUE)
    assert cache.get({"params": {"M": 1.0}, "omega": 1.0, "F": 10.0, "kind": "df"}) == VALUE
    assert cache.get(dict(KEY, F=10.000000000000002)) is None  # a different float is a different point
    assert (cache.hits, cache.misses, cache.rejected) == (1, 1, 0)
    assert not list(tmp_path.rglob("*.partial"))


@pytest.mark.parametrize("damage", ["truncate", "garbage", "value", "checksum", "format", "key", "no header"])
def test_a_damaged_or_foreign_entry_is_rejected_not_trusted(tmp_path, damage):
    cache = Cache(tmp_path)
    cache.put(KEY, VALUE)
    [path] = [p for p in tmp_path.rglob("*.json")]
    data = path.read_bytes()
    head, body = data.split(b"\n", 1)
    entry = json.loads(head)
    if damage == "truncate":
        data = data[: len(data) - 5]
    elif damage == "garbage":
        data = b"\x00\xff" * 10
    elif damage == "value":
        data = head + b"\n" + body.replace(b"-0.25", b"-0.26")  # changed without its checksum
    elif damage == "no header":
        data = body
    else:
        if damage == "checksum":
            entry["sha256"] = "0" * 64
        elif damage == "format":
            entry["format"] = cache_module.FORMAT + 1
        elif damage == "key":
            entry["key"] = entry["key"].replace("10.0", "20.0")  # an entry filed under the wrong name
        data = json.dumps(entry).encode() + b"\n" + body
    path.write_bytes(data)
    assert cache.get(KEY) is None and cache.rejected == 1
    cache.put(KEY, VALUE)  # recomputed and stored again
    assert cache.get(KEY) == VALUE


def test_values_must_be_finite(tmp_path):
    with pytest.raises(ValueError):
        Cache(tmp_path).put(KEY, {"x": float("nan")})


def test_the_default_directory_follows_xdg_then_home(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert default_dir() == tmp_path / "xdg" / "dfwb"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert default_dir() == tmp_path / "home" / ".cache" / "dfwb"


def test_no_cache_finds_and_keeps_nothing():
    off = NoCache()
    off.put(KEY, VALUE)
    assert off.get(KEY) is None and off.misses == 1


def test_entries_written_in_the_background_are_all_there_when_writing_ends(tmp_path):
    cache = Cache(tmp_path)
    keys = [dict(KEY, F=float(n)) for n in range(50)]
    with cache.writing():
        for n, key in enumerate(keys):
            cache.put(key, dict(VALUE, N_re=float(n)))
        assert cache.get(keys[7]) == dict(VALUE, N_re=7.0)  # a pending entry is read once written
    assert [cache.get(key)["N_re"] for key in keys] == [float(n) for n in range(50)]
    assert not list(tmp_path.rglob("*.partial")) and cache.failed == 0


def test_a_cache_that_cannot_be_written_in_the_background_warns_once_when_writing_ends(tmp_path):
    (tmp_path / "cache").write_text("a file where the cache's folder belongs")
    cache = Cache(tmp_path / "cache")
    with pytest.warns(cache_module.CacheWarning, match="cannot be written") as caught:
        with cache.writing():
            for n in range(3):
                cache.put(dict(KEY, F=float(n)), VALUE)  # never raises
    assert len(caught) == 1 and cache.failed == 3 and cache.get(KEY) is None
