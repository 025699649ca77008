"""Where the FMUs are built, which ones, and which sources each one's hash covers."""

import os
import subprocess
import sys

from dfwb.build_fmus import builder
from dfwb.fmi import location
from dfwb.fmus import facade, loop_facade, naive_facade


def test_default_folder_follows_dfwb_fmu_dir_then_xdg_cache_home_then_home(tmp_path, monkeypatch):
    monkeypatch.setenv("DFWB_FMU_DIR", str(tmp_path / "chosen"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert location.default_fmu_dir() == tmp_path / "chosen"
    monkeypatch.delenv("DFWB_FMU_DIR")
    assert location.default_fmu_dir() == tmp_path / "xdg" / "dfwb" / "fmus"
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert location.default_fmu_dir() == tmp_path / "home" / ".cache" / "dfwb" / "fmus"


def test_a_command_creates_nothing_where_the_user_stands(tmp_path):
    """``dfwb df`` builds the one FMU it needs into the user's cache, not into ./build/fmus."""
    cwd, cache = tmp_path / "cwd", tmp_path / "xdg"
    cwd.mkdir()
    env = {name: value for name, value in os.environ.items() if name != "DFWB_FMU_DIR"}
    env["XDG_CACHE_HOME"] = str(cache)
    done = subprocess.run([sys.executable, "-m", "dfwb.cli", "df", "friction", "--F", "10", "--omega", "1"],
                          cwd=cwd, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert list(cwd.iterdir()) == []
    folder = cache / "dfwb" / "fmus"  # the native FMU by default, in the folder's native/
    assert [path.name for path in folder.iterdir()] == ["native"]
    assert [path.name for path in (folder / "native").iterdir()] == ["FrictionMass.fmu"]


def test_fmu_path_builds_only_the_fmu_asked_for(tmp_path):
    path = location.fmu_path("LinearSystem", tmp_path)
    assert path == tmp_path / "LinearSystem.fmu"
    assert [p.name for p in tmp_path.iterdir()] == ["LinearSystem.fmu"]


def test_models_are_the_registry_plants_the_controller_and_the_loops_the_twins_when_asked():
    production = location.models()
    assert set(production) == set(facade.PRODUCTION + loop_facade.LOOPS)
    assert set(location.models(naive=True)) == set(facade.PRODUCTION + loop_facade.LOOPS + naive_facade.NAIVE)


def _copy_sources(tmp_path, monkeypatch):
    sources = tmp_path / "sources"
    sources.mkdir()
    for path in builder.FMUS_DIR.glob("*.py"):
        (sources / path.name).write_bytes(path.read_bytes())
    monkeypatch.setattr(builder, "FMUS_DIR", sources)
    return sources


def test_editing_the_naive_module_leaves_the_production_hashes_alone(tmp_path, monkeypatch):
    production = {model: builder.source_hash(model) for model in facade.PRODUCTION}
    twins = {model: builder.source_hash(model) for model in naive_facade.NAIVE}
    plants = {production[model] for model in facade.PRODUCTION if builder.native(model)}
    assert len(plants) == 1 and len(set(production.values())) == 2  # the plants' hash covers the C core too
    assert set(production.values()).isdisjoint(twins.values())
    for model in facade.PRODUCTION:
        assert "naive.py" not in builder.sources(model) and "naive_facade.py" not in builder.sources(model)

    sources = _copy_sources(tmp_path, monkeypatch)
    for name in ("naive.py", "naive_facade.py"):
        (sources / name).write_text((sources / name).read_text() + "\n# edited\n")
        assert {model: builder.source_hash(model) for model in facade.PRODUCTION} == production
        changed = {model: builder.source_hash(model) for model in naive_facade.NAIVE}
        assert all(changed[model] != twins[model] for model in twins)


def test_an_edit_inside_the_closure_changes_every_fmu_that_bundles_it(tmp_path, monkeypatch):
    before = {model: builder.source_hash(model) for model in facade.PRODUCTION + naive_facade.NAIVE}
    sources = _copy_sources(tmp_path, monkeypatch)
    (sources / "exact.py").write_text((sources / "exact.py").read_text() + "\n# edited\n")
    after = {model: builder.source_hash(model) for model in before}
    assert all(after[model] != before[model] for model in before)


def test_a_naive_edit_does_not_rebuild_a_production_fmu(tmp_path, monkeypatch):
    out = tmp_path / "fmus"
    messages = []
    builder.build(out, [facade.StaticBacklash], report=messages.append)
    sources = _copy_sources(tmp_path, monkeypatch)
    (sources / "naive.py").write_text((sources / "naive.py").read_text() + "\n# edited\n")
    builder.build(out, [facade.StaticBacklash], report=messages.append)
    assert [message.rpartition(": ")[2] for message in messages] == ["built", "up to date"]
