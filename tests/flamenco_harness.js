// Runs a Flamenco 3 job compiler script under Node with a small stand-in for the Manager's documented API:
// the global `author` (Task(name, type), Command(name, parameters)), `print`, and the `job` passed to
// compileJob(job) (job.settings, job.addTask(task)); task.addCommand(command), task.addDependency(task).
//
//     node flamenco_harness.js JOB_SCRIPT.js < {"settings": {...}}
//
// Prints {"label", "settings", "tasks": [{name, type, commands: [{name, parameters}], dependencies}]} as
// JSON and exits 0, or prints {"error": "..."} and exits 1 when compileJob throws a message (a string, as
// the Manager's own scripts do); any other exception is a defect and ends Node with its stack trace.
"use strict";
const fs = require("fs");
const vm = require("vm");

function check(ok, message) {
    if (!ok) throw new TypeError(`job compiler API misuse: ${message}`);
}

class Task {
    constructor(name, type) {
        check(typeof name === "string" && name !== "", `task name must be a non-empty string, got ${name}`);
        check(typeof type === "string" && type !== "", `task type must be a non-empty string, got ${type}`);
        this.name = name;
        this.type = type;
        this.commands = [];
        this.dependencies = [];
    }
    addCommand(command) {
        check(command && typeof command.name === "string", "addCommand() takes an author.Command()");
        this.commands.push(command);
    }
    addDependency(task) {
        check(task instanceof Task, "addDependency() takes an author.Task()");
        this.dependencies.push(task.name);
    }
}

const author = {
    Task: (name, type) => new Task(name, type),
    Command: (name, parameters) => {
        check(typeof name === "string" && name !== "", "command name must be a non-empty string");
        check(parameters !== null && typeof parameters === "object", "command parameters must be an object");
        return { name, parameters: JSON.parse(JSON.stringify(parameters)) };
    },
};

const script = process.argv[2];
const input = JSON.parse(fs.readFileSync(0, "utf8"));
const context = vm.createContext({ author, print: (...a) => process.stderr.write(a.join(" ") + "\n") });
vm.runInContext(`${fs.readFileSync(script, "utf8")}\n;globalThis.__jobType = { JOB_TYPE, compileJob };`,
                context, { filename: script });
const { JOB_TYPE, compileJob } = context.__jobType;

const tasks = [];
const job = {
    name: "test job",
    created: new Date(0),
    settings: input.settings,
    addTask(task) {
        check(task instanceof Task, "job.addTask() takes an author.Task()");
        check(!tasks.some((t) => t.name === task.name), `two tasks are named '${task.name}'`);
        tasks.push(task);
    },
};
try {
    compileJob(job);
} catch (e) {
    // The Manager shows a thrown message as the job's error; anything else is a defect in the script.
    if (typeof e !== "string") throw e;
    process.stdout.write(JSON.stringify({ error: e }));
    process.exit(1);
}
process.stdout.write(JSON.stringify({
    label: JOB_TYPE.label,
    settings: JOB_TYPE.settings,
    tasks: tasks.map(({ name, type, commands, dependencies }) => ({ name, type, commands, dependencies })),
}));
