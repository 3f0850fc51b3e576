"""A curve that fills the unit's curve memory (overflow policy stop) is flagged on the wire (end marker MemoryFull),
in /device/result, results.csv, the console and the report, and its NOK reasons say it was cut."""
from __future__ import annotations

import csv
from pathlib import Path

import cantools

from rig.analysis.sets import CUT_BY_MEMORY
from rig.cli import main
from rig.recorder import read_recording

ROOT = Path(__file__).resolve().parents[2]


def test_a_curve_cut_by_the_full_memory_is_flagged_everywhere(tmp_path, capsys):
    text = (ROOT / "data" / "scenes" / "pin_insertion.toml").read_text()
    fast = text.replace('sample_rate = "10 kHz"', 'sample_rate = "100 kHz"', 1).replace('delta = "0.1 ms"',
                                                                                         'delta = "0.01 ms"', 1)
    assert fast != text
    scene = tmp_path / "fast.toml"
    scene.write_text(fast)
    out = tmp_path / "fast.mcap"
    assert main(["run", str(scene), "--cycles", "3", "-o", str(out), "--format", "md"]) == 0
    console = capsys.readouterr().out
    assert "3 curve(s) filled the unit's curve memory and were cut there (curve 1, 2, 3)" in console
    rec = read_recording(out)
    assert [r.get("memory_full") for r in rec.results] == [True] * 3
    db = cantools.database.load_file(ROOT / "data" / "can" / "rig.dbc")
    marker = db.get_message_by_name("ResultValue").frame_id
    ends = [db.decode_message(marker, bytes(d)) for i, d in zip(rec.can_frames["id"], rec.can_frames["data"])
            if i == marker and bytes(d)[2] == 255]
    assert [e["MemoryFull"] for e in ends] == [1] * 3 and [e["Decimated"] for e in ends] == [0] * 3
    rows = list(csv.DictReader((tmp_path / "fast" / "results.csv").open(encoding="utf-8")))
    assert [r["memory"] for r in rows] == ["cut"] * 3
    assert all(r["verdict"] == "NOK" and r["reason"].startswith(CUT_BY_MEMORY + "; ") for r in rows)
    assert "the curve never reaches that range" in rows[0]["reason"]
    report = (tmp_path / "fast" / "report.md").read_text(encoding="utf-8")
    assert "filled the unit's curve memory and were cut there" in report
    # the end-of-run records (statistics, link summary) are stamped at the run's end, after the unit's last
    # reports — not at the host theory's coverage, which lagged by a second here: no topic's log time decreases
    from mcap.reader import make_reader
    last: dict[str, int] = {}
    with open(out, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            assert message.log_time >= last.get(channel.topic, 0), channel.topic
            last[channel.topic] = message.log_time


def test_a_demo_result_carries_no_memory_flag(tmp_path):
    out = tmp_path / "demo.mcap"
    assert main(["-q", "run", str(ROOT / "data" / "scenes" / "pin_insertion.toml"), "--cycles", "1", "-o", str(out),
                 "--no-report"]) == 0
    assert "memory_full" not in read_recording(out).results[0]
