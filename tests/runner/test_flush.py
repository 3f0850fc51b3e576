"""The end-of-run flush waits only for frames queued before it, not for heartbeats that keep coming."""
from __future__ import annotations

from pathlib import Path

from rig.runner import run_scene

SCENES = Path(__file__).resolve().parents[2] / "data" / "scenes"


def test_flush_ends_when_chunk_is_a_multiple_of_the_heartbeat(tmp_path):
    # 0.1 s chunks (the scene's): every advance_to() of the run lands on a heartbeat that cannot be on the wire yet
    text = (SCENES / "clutch_startup.toml").read_text()
    assert 'chunk = "100 ms"' in text
    text = text.replace('duration = "0.8 s"', 'duration = "0.3 s"')
    scene = tmp_path / "chunky.toml"
    scene.write_text(text)
    summary = run_scene(scene, tmp_path / "chunky.mcap")
    assert 0.3 <= summary.simulated_time < 0.35         # before the fix: ran on for the 60 s flush limit; the flush
                                                        # drains in 5 ms steps, not whole chunks


def test_a_stand_run_keeps_no_theory_blocks(tmp_path, monkeypatch):
    """The host keeps theory blocks only for curves still to come; a stand scene has no curves (the unit's channels
    are not wired), so none is held: its memory does not grow with the run (0.5 MB per simulated s before)."""
    from rig.runner.host import Host
    held = []
    finish = Host.finish

    def counting(self, *args, **kwargs):
        held.append(len(self._truth))
        return finish(self, *args, **kwargs)

    monkeypatch.setattr(Host, "finish", counting)
    text = (SCENES / "clutch_blocked.toml").read_text().replace('duration = "10 s"', 'duration = "2 s"')
    scene = tmp_path / "blocked.toml"
    scene.write_text(text)
    summary = run_scene(scene, tmp_path / "blocked.mcap")
    assert summary.simulated_time >= 2.0 and held == [0]
