"""The Flamenco job type (farm/flamenco/restir_gi_render.js) compiled by
node with stand-ins for the Manager's job-compiler API (author.Task,
author.Command, frameChunker, formatTimestampLocal): one task per chunk,
each rendering its chunk as one animation job with the engine selected and
the chunk warm-up set before --render-frame; bad settings are refused."""

import json
import shutil
import subprocess
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "farm" / "flamenco" / "restir_gi_render.js"

HARNESS = r"""
const fs = require("fs"), vm = require("vm");
const job = JSON.parse(process.argv[3]);
const tasks = [];
const sandbox = {
  print: () => {},
  formatTimestampLocal: () => "2026-12-01_10-00-00",
  frameChunker: (frames, size) => {      // Flamenco's: ranges split into chunks
    const out = [];
    for (const part of frames.split(",")) {
      const [a, b] = part.trim().split("-").map(Number);
      const last = b === undefined ? a : b;
      for (let s = a; s <= last; s += size) {
        const e = Math.min(s + size - 1, last);
        out.push(s === e ? `${s}` : `${s}-${e}`);
      }
    }
    return out;
  },
  author: {
    Task: (name, type) => ({ name, type, commands: [], addCommand(c) { this.commands.push(c); } }),
    Command: (type, params) => ({ type, params }),
  },
};
job.addTask = (t) => tasks.push(t);
vm.createContext(sandbox);
vm.runInContext(fs.readFileSync(process.argv[2], "utf8") + "\nthis.compileJob = compileJob; this.JOB_TYPE = JOB_TYPE;", sandbox);
try {
  sandbox.compileJob(job);
  console.log(JSON.stringify({ tasks, settings: job.settings, type: sandbox.JOB_TYPE }));
} catch (e) {
  console.log(JSON.stringify({ error: String(e) }));
}
"""

pytestmark = pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")


def compile_job(tmp_path, **settings):
    harness = tmp_path / "harness.js"
    harness.write_text(HARNESS)
    job = {"created": "2026-12-01T10:00:00Z", "settings": {
        "frames": "1-20", "chunk_size": 8, "chunk_warmup": 16, "format": "OPEN_EXR_MULTILAYER",
        "blendfile": "/shared/shot.blend", "render_output_path": "/shared/out/shot/{timestamp}/######",
        **settings}}
    out = subprocess.run(["node", str(harness), str(SCRIPT), json.dumps(job)],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def test_one_task_per_chunk_with_the_warmup_before_the_render(tmp_path):
    result = compile_job(tmp_path)
    assert "error" not in result, result
    chunks = [t["name"] for t in result["tasks"]]
    assert chunks == ["render-1-8", "render-9-16", "render-17-20"]
    for task, frames in zip(result["tasks"], ("1..8", "9..16", "17..20")):
        (cmd,) = task["commands"]
        assert cmd["type"] == "blender-render" and cmd["params"]["blendfile"] == "/shared/shot.blend"
        args = cmd["params"]["args"]
        # Blender reads its arguments in order: engine and setting before the render.
        assert args[-2:] == ["--render-frame", frames]
        assert args.index("--engine") < args.index("--python-expr") < args.index("--render-frame")
        assert args[args.index("--engine") + 1] == "RESTIR_GI"
        assert "chunk_warmup_frames = 16" in args[args.index("--python-expr") + 1]
        assert args[args.index("--render-output") + 1] == "/shared/out/shot/2026-12-01_10-00-00/######"
    assert result["settings"]["render_output_path"].endswith("2026-12-01_10-00-00/######")
    keys = {s["key"] for s in result["type"]["settings"]}
    assert {"frames", "chunk_size", "chunk_warmup", "blendfile", "render_output_path"} <= keys


def test_single_frames_and_lists(tmp_path):
    result = compile_job(tmp_path, frames="3, 10-12", chunk_size=2, chunk_warmup=0)
    frames = [t["commands"][0]["params"]["args"][-1] for t in result["tasks"]]
    assert frames == ["3", "10..11", "12"]


@pytest.mark.parametrize("settings", [{"format": "FFMPEG"}, {"chunk_warmup": -1},
                                      {"chunk_warmup": "x"}, {"render_output_path": ""}])
def test_bad_settings_are_refused(tmp_path, settings):
    result = compile_job(tmp_path, **settings)
    assert "error" in result and not result.get("tasks"), result
