"""The "Install PyTorch" button obeys Blender's "Allow Online Access" setting."""
from __future__ import annotations

import pytest

bpy = pytest.importorskip("bpy")


@pytest.fixture
def no_pip(monkeypatch):
    """Records every process the installer would start instead of starting it."""
    from remogen_blender import deps
    started: list = []

    def record(cmd, *args, **kwargs):
        started.append(cmd)
        raise AssertionError(f"started {cmd}")
    monkeypatch.setattr(deps.subprocess, "Popen", record)
    monkeypatch.setattr(deps.subprocess, "run", record)
    return started


def test_reads_blenders_online_access_setting():
    from remogen_blender import deps
    assert deps.online_access_allowed() is bool(bpy.app.online_access)


def test_button_refuses_when_online_access_is_off(addon, monkeypatch, no_pip, tmp_path):
    from remogen_blender import _runtime, deps
    if bpy.app.online_access:     # the bpy module starts with it off; otherwise switch it off for the test
        monkeypatch.setattr(deps, "online_access_allowed", lambda: False)
    made: list = []
    monkeypatch.setattr(_runtime, "private_site_packages", lambda create=False: made.append(create) or tmp_path)
    with pytest.raises(RuntimeError) as err:
        bpy.ops.remogen.install_torch()
    assert str(err.value).strip() == f"Error: {deps.OFFLINE_REFUSAL}"
    assert "Preferences > System > Network > Allow Online Access" in deps.OFFLINE_REFUSAL
    assert "\n" not in deps.OFFLINE_REFUSAL
    assert no_pip == [] and made == []                       # no pip, no folder
    assert deps.status.line == deps.OFFLINE_REFUSAL and not deps.status.ok


def test_install_refuses_network_sources_when_offline(monkeypatch, no_pip, tmp_path):
    from remogen_blender import deps
    monkeypatch.setattr(deps, "online_access_allowed", lambda: False)
    for index, links, no_index in ((deps.DEFAULT_INDEX, None, False), (None, None, False),
                                   (None, "https://example.org/wheels/", True)):
        assert deps.install(tmp_path / "site", "torch", index, links, no_index) == (False, deps.OFFLINE_REFUSAL)
    assert no_pip == [] and not (tmp_path / "site").exists()
    # local wheels need no network: allowed while offline
    assert deps.offline_refusal(None, str(tmp_path), no_index=True) is None
    assert deps.offline_refusal("file://" + str(tmp_path)) is None


def test_online_access_on_lets_pip_run(monkeypatch):
    from remogen_blender import deps
    monkeypatch.setattr(deps, "online_access_allowed", lambda: True)
    assert deps.offline_refusal(deps.DEFAULT_INDEX) is None
