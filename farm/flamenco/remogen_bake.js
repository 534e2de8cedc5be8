// SPDX-License-Identifier: GPL-3.0-or-later
//
// Flamenco 3 job type "ReMoGen bake": bakes the ReMoGen ego's reaction headless on the farm's workers.
//
// Install: copy this file into the `scripts` folder next to the flamenco-manager executable and restart
// the Manager. Every worker's Blender needs the ReMoGen extension installed and enabled (the extension
// zip with PyTorch bundled needs no download on the worker).
//
// Each bake is one .blend file x one ego x one frame range, saved to its own output file. A task runs
//     {blender} {blenderArgs} FILE -c remogen bake --blend FILE [options] --output OUTPUT
// `--blend FILE` repeats the file so that the bake reports a missing file in one line, whatever Blender
// did with the file argument before the command ran.

const SEED_MAX = 2147483647; // the extension's seed bound (a 32-bit seed)
const OUTPUT_FIELDS = ["file", "ego", "frames"];

const JOB_TYPE = {
    label: "ReMoGen bake",
    description: "Bake ReMoGen ego reactions into new .blend files: one per shot, ego and frame chunk",
    settings: [
        // What to bake.
        { key: "blendfile", type: "string", visible: "web",
          description: "The submitted .blend file (the Flamenco add-on fills it in); baked unless empty" },
        { key: "shot_files", type: "string", default: "", visible: "submission",
          description: "More .blend files (shots) to bake with the same settings, as the workers see them, " +
                       "separated by ';' or new lines" },
        { key: "egos", type: "string", default: "", visible: "submission",
          description: "Ego armatures to bake, separated by commas, each into its own file; " +
                       "empty: each file's ego (created when the file has none)" },
        { key: "frames", type: "string", default: "",
          eval: "f'{C.scene.frame_start}-{C.scene.frame_end}'",
          evalInfo: { showLinkButton: true, description: "Scene frame range" },
          description: "Frame range START-END, e.g. '1-240'; empty: each file's scene range" },

        // How: empty or -1 keeps the value saved in each file.
        { key: "text", type: "string", default: "",
          description: "Intent text, e.g. 'walk to the person and wave'; empty: each file's own" },
        { key: "alpha_hhi", type: "float", default: -1, propargs: { min: -1, max: 1 },
          description: "Partner influence 0-1; -1: each file's own" },
        { key: "alpha_hsi", type: "float", default: -1, propargs: { min: -1, max: 1 },
          description: "Scene influence 0-1; -1: each file's own" },
        { key: "seed", type: "int32", default: -1, propargs: { min: -1 },
          description: "Random seed 0-2147483647; -1: each file's own" },

        // Chunking.
        { key: "frames_per_task", type: "int32", default: 0, propargs: { min: 0 }, visible: "submission",
          description: "Split the frame range into bakes of this many frames, each generated on its own " +
                       "into its own file (the motion does not carry over between them); 0: one bake" },
        { key: "bakes_per_task", type: "int32", default: 1, propargs: { min: 1 }, visible: "submission",
          description: "Bakes one task runs one after another (fewer, longer tasks)" },

        // Where to.
        { key: "output_dir", type: "string", subtype: "dir_path", required: true, visible: "submission",
          eval: "str(Path(abspath('//'), 'remogen_bakes'))",
          evalInfo: { showLinkButton: true, description: "A 'remogen_bakes' folder beside the blend file" },
          description: "Folder the baked .blend files are saved in, as the workers see it" },
        { key: "output_name", type: "string", default: "{file}_{ego}_{frames}.blend", visible: "submission",
          description: "File name of each bake: {file} the shot's file name, {ego} the ego ('ego' for the " +
                       "file's own), {frames} START-END ('scene' for the file's range)" },
    ],
};

function compileJob(job) {
    const settings = readSettings(job.settings || {});
    const bakes = planBakes(settings);
    for (const task of authorTasks(bakes, settings)) {
        job.addTask(task);
    }
}

// ---------------------------------------------------------------- settings

function fail(message) {
    throw `ReMoGen bake: ${message}`;
}

function defaultOf(key) {
    const setting = JOB_TYPE.settings.find((s) => s.key === key);
    return setting ? setting.default : undefined;
}

// The job's value, or the job type's default when the submission left it out.
function value(raw, key) {
    const v = raw[key];
    return v === undefined || v === null ? defaultOf(key) : v;
}

function text(raw, key) {
    const v = value(raw, key);
    if (v === undefined) return "";
    if (typeof v !== "string") fail(`${key} must be text, got ${JSON.stringify(v)}`);
    return v.trim();
}

function number(raw, key, { min, max, integer, keep }) {
    let v = value(raw, key);
    if (typeof v === "string" && v.trim() !== "") v = Number(v);
    const range = max === undefined ? `${min} or more` : `between ${min} and ${max}`;
    const hint = keep ? " (or -1 to keep each file's own)" : "";
    const ok = typeof v === "number" && Number.isFinite(v) && (!integer || Number.isInteger(v));
    if (ok && v === -1 && keep) return -1;
    if (!ok || v < min || (max !== undefined && v > max)) {
        fail(`${key} must be ${integer ? "a whole number " : ""}${range}${hint}, got ${JSON.stringify(value(raw, key))}`);
    }
    return v;
}

function splitList(s, separators) {
    return s.split(separators).map((x) => x.trim()).filter((x) => x !== "");
}

function parseFrames(s) {
    if (s === "") return null;
    const m = /^(-?\d+)\s*(?:-|\.\.)\s*(-?\d+)$/.exec(s);
    if (!m) fail(`frames must be a range START-END like '1-240', got '${s}'`);
    const range = [Number(m[1]), Number(m[2])];
    if (range[1] < range[0]) fail(`frames '${s}' is empty: the end frame must not be before the start`);
    return range;
}

function readSettings(raw) {
    const files = [];
    for (const f of [text(raw, "blendfile"), ...splitList(text(raw, "shot_files"), /[;\n]/)]) {
        if (f === "") continue;
        if (!/\.blend$/i.test(f)) fail(`'${f}' is not a .blend file`);
        if (!files.includes(f)) files.push(f);
    }
    if (files.length === 0) fail("no .blend file to bake: submit from a saved file or list shot_files");

    const egos = splitList(text(raw, "egos"), ",");
    const duplicate = egos.find((e, i) => egos.indexOf(e) !== i);
    if (duplicate !== undefined) fail(`ego '${duplicate}' is listed twice in egos`);

    const settings = {
        files,
        egos,
        frames: parseFrames(text(raw, "frames")),
        text: text(raw, "text"),
        alpha_hhi: number(raw, "alpha_hhi", { min: 0, max: 1, keep: true }),
        alpha_hsi: number(raw, "alpha_hsi", { min: 0, max: 1, keep: true }),
        seed: number(raw, "seed", { min: 0, max: SEED_MAX, integer: true, keep: true }),
        frames_per_task: number(raw, "frames_per_task", { min: 0, integer: true }),
        bakes_per_task: number(raw, "bakes_per_task", { min: 1, integer: true }),
        output_dir: text(raw, "output_dir"),
        output_name: text(raw, "output_name"),
    };
    if (settings.frames_per_task > 0 && settings.frames === null) {
        fail("frames_per_task needs a frame range in frames (each file's own range is not known here)");
    }
    if (settings.output_dir === "") fail("output_dir is empty: name the folder the bakes are saved in");
    checkOutputName(settings.output_name);
    return settings;
}

function checkOutputName(name) {
    if (/[\\/]/.test(name)) fail(`output_name '${name}' must be a file name, not a path: put folders in output_dir`);
    if (!/\.blend$/i.test(name)) fail(`output_name '${name}' must end in .blend`);
    name.replace(/\{([^}]*)\}/g, (match, field) => {
        if (!OUTPUT_FIELDS.includes(field)) {
            fail(`output_name has an unknown field {${field}}: use ${OUTPUT_FIELDS.map((f) => `{${f}}`).join(", ")}`);
        }
        return match;
    });
}

// ---------------------------------------------------------------- bakes

function fileStem(file) {
    // The Flamenco add-on submits a copy named NAME.flamenco.blend.
    return file.split(/[\\/]/).pop().replace(/\.blend$/i, "").replace(/\.flamenco$/, "");
}

function joinPath(dir, name) {
    const windows = dir.includes("\\") && !dir.includes("/");
    return dir.replace(/[\\/]+$/, "") + (windows ? "\\" : "/") + name;
}

function safeName(s) {
    return s.replace(/[^A-Za-z0-9._-]/g, "_");
}

function frameChunks(frames, perChunk) {
    if (frames === null || perChunk === 0) return [frames];
    const chunks = [];
    for (let start = frames[0]; start <= frames[1]; start += perChunk) {
        chunks.push([start, Math.min(start + perChunk - 1, frames[1])]);
    }
    return chunks;
}

// Every (file, ego, frame chunk) with its output file; two bakes never share an output, and no output
// is one of the files being baked.
function planBakes(settings) {
    const bakes = [];
    const byOutput = new Map();
    for (const file of settings.files) {
        for (const ego of settings.egos.length ? settings.egos : [null]) {
            for (const frames of frameChunks(settings.frames, settings.frames_per_task)) {
                const fields = {
                    file: fileStem(file),
                    ego: ego === null ? "ego" : safeName(ego),
                    frames: frames === null ? "scene" : `${frames[0]}-${frames[1]}`,
                };
                const name = settings.output_name.replace(/\{(\w+)\}/g, (_, f) => fields[f]);
                const output = joinPath(settings.output_dir, name);
                const bake = { file, ego, frames, output, label: `${fields.file} ${fields.ego} ${fields.frames}` };
                if (settings.files.includes(output)) {
                    fail(`the output of ${bake.label} would overwrite the shot file '${output}': change output_name or output_dir`);
                }
                if (byOutput.has(output)) {
                    fail(`${byOutput.get(output).label} and ${bake.label} would both save '${output}': ` +
                         "put {file}, {ego} and {frames} in output_name");
                }
                byOutput.set(output, bake);
                bakes.push(bake);
            }
        }
    }
    return bakes;
}

// The arguments after the file: `-c remogen bake ...`, with exactly the extension's command-line options.
// `--opt=value` keeps a value that starts with '-' from reading as an option.
function bakeArgs(settings, bake) {
    const args = ["-c", "remogen", "bake", `--blend=${bake.file}`];
    if (bake.ego !== null) args.push(`--ego=${bake.ego}`);
    if (settings.text !== "") args.push(`--text=${settings.text}`);
    if (settings.alpha_hhi !== -1) args.push(`--alpha-hhi=${settings.alpha_hhi}`);
    if (settings.alpha_hsi !== -1) args.push(`--alpha-hsi=${settings.alpha_hsi}`);
    if (settings.seed !== -1) args.push(`--seed=${settings.seed}`);
    if (bake.frames !== null) args.push("--frames", String(bake.frames[0]), String(bake.frames[1]));
    args.push(`--output=${bake.output}`);
    return args;
}

function authorTasks(bakes, settings) {
    const tasks = [];
    for (let i = 0; i < bakes.length; i += settings.bakes_per_task) {
        const group = bakes.slice(i, i + settings.bakes_per_task);
        const more = group.length > 1 ? ` +${group.length - 1}` : "";
        const task = author.Task(`bake ${group[0].label}${more}`, "blender");
        for (const bake of group) {
            task.addCommand(author.Command("blender-render", {
                exe: "{blender}",
                exeArgs: "{blenderArgs}",
                argsBefore: [],
                blendfile: bake.file,
                args: bakeArgs(settings, bake),
            }));
        }
        tasks.push(task);
    }
    return tasks;
}
