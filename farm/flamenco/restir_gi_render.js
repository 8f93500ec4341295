// Flamenco job type: render a ReSTIR GI animation in chunks of frames.
//
// Each task renders one chunk with `blender -b FILE -E RESTIR_GI
// --python-expr ... --render-frame A..B`. Blender renders A..B as one
// animation job and the engine's chunk warm-up first renders the frames
// before A along the animation (not written, no "Saved:" lines), so a chunk's
// first frame has the history a continuous render would have there. The
// warm-up length is a job setting (default: the file's Chunk Warm-up).
//
// Install: copy this file into the `scripts` folder next to the Flamenco
// Manager executable and restart the Manager; workers need the restir_gi
// extension installed in their Blender (see farm/flamenco/README.md).

const JOB_TYPE = {
    label: "ReSTIR GI Render",
    description: "Render frames with the ReSTIR GI engine, each chunk warmed up along the animation",
    settings: [
        { key: "frames", type: "string", required: true,
          eval: "f'{C.scene.frame_start}-{C.scene.frame_end}'",
          description: "Frame range to render, e.g. '1-240' or '1-30, 40-50'" },
        { key: "chunk_size", type: "int32", default: 8, propargs: { min: 1 }, visible: "submission",
          description: "Frames per task; each task also renders its warm-up frames" },
        { key: "chunk_warmup", type: "int32", propargs: { min: 0, max: 4096 }, visible: "submission",
          eval: "C.scene.restir_gi.chunk_warmup_frames",
          description: "Frames rendered (not written) before each chunk's first frame" },
        { key: "render_output_root", type: "string", subtype: "dir_path", required: true,
          visible: "submission", description: "Folder the job's output folder goes into" },
        { key: "add_path_components", type: "int32", required: true, default: 0,
          propargs: { min: 0, max: 32 }, visible: "submission",
          description: "Number of path components of the blend file's folder to repeat below the root" },
        { key: "render_output_path", type: "string", subtype: "file_path", editable: false,
          eval: "str(Path(abspath(settings.render_output_root), last_n_dir_parts(settings.add_path_components), jobname, '{timestamp}', '######'))",
          description: "Where the frames are written" },
        { key: "blendfile", type: "string", required: true, visible: "web",
          description: "Blend file to render" },
        { key: "format", type: "string", required: true, visible: "web",
          eval: "C.scene.render.image_settings.file_format" },
    ],
};

const MOVIE_FORMATS = ["FFMPEG", "AVI_RAW", "AVI_JPEG"];

function compileJob(job) {
    const settings = job.settings;
    if (MOVIE_FORMATS.indexOf(settings.format) >= 0) {
        throw `ReSTIR GI Render writes image files per frame, not "${settings.format}": ` +
              "chunks rendered on different workers cannot append to one movie file";
    }
    const warmup = Number(settings.chunk_warmup);
    if (!Number.isInteger(warmup) || warmup < 0) {
        throw `chunk_warmup must be a whole number of frames >= 0, not "${settings.chunk_warmup}"`;
    }
    const output = expandOutputPath(settings.render_output_path, job.created);
    settings.render_output_path = output;   // shown on the job as it was used

    for (const chunk of frameChunker(settings.frames, settings.chunk_size)) {
        job.addTask(chunkTask(settings, chunk, warmup, output));
    }
}

// One task: Blender renders the chunk "A-B" (or "A") as one animation job.
function chunkTask(settings, chunk, warmup, output) {
    const task = author.Task(`render-${chunk}`, "blender");
    task.addCommand(author.Command("blender-render", {
        exe: "{blender}",
        exeArgs: "{blenderArgs}",
        argsBefore: [],
        blendfile: settings.blendfile,
        args: blenderArgs(chunk, warmup, output, settings.format),
    }));
    return task;
}

// Blender reads its arguments in order: the engine and the setting come
// before --render-frame, which renders.
function blenderArgs(chunk, warmup, output, format) {
    return [
        "--engine", "RESTIR_GI",
        "--python-expr",
        `import bpy; bpy.context.scene.restir_gi.chunk_warmup_frames = ${warmup}`,
        "--render-output", output,
        "--render-format", format,
        "--render-frame", chunk.replace("-", ".."),
    ];
}

function expandOutputPath(template, created) {
    if (!template) {
        throw "the job has no render_output_path";
    }
    return template.replace(/{timestamp}/g, () => formatTimestampLocal(created));
}
