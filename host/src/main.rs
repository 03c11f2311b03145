//! `hvs`: the host side of hvs-depth. Commands parse arguments and do I/O; all math is in
//! `hvs-shared`. Each subcommand lives in `hvs_host::cli::<name>` with its own clap `Args`
//! and `run`; adding one is a variant here and a match arm below.

use clap::{Parser, Subcommand};
use hvs_host::cli as cmd;

#[derive(Parser)]
#[command(
    name = "hvs",
    version,
    about = "Calibration-free stereo depth for a humanoid vision system",
    long_about = "Calibration-free stereo depth for a humanoid vision system.\n\n\
    Start with `hvs demo`: it simulates the thesis' four camera cases, trains the 4-5-3 \
    net on each and compares it with the traditional method."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    Simulate(cmd::simulate::Args),
    Train(cmd::train::Args),
    Predict(cmd::predict::Args),
    Eval(cmd::eval::Args),
    Info(cmd::info::Args),
    Demo(cmd::demo::Args),
    Experiment(cmd::experiment::Args),
    /// Stereo photos of a chessboard through a rig, with exact corner truth.
    Render(cmd::render::Args),
    /// The head in the loop (virtual cameras on a scene, or real ones; the head emulated, in QEMU or on a port): keeps a target in the middle of both eyes.
    Track(cmd::track::Args),
    /// Board photos into a training set (`hvs board detect`).
    Board(cmd::board::Args),
    Collect(cmd::collect::Args),
    Locate(cmd::locate::Args),
    Depth(cmd::depth::Args),
    /// Boot the head firmware in QEMU with a model in slot A.
    Emulate(cmd::emulate::Args),
    /// Talk to a head (QEMU over TCP, or a serial port).
    Head(cmd::head::Args),
    /// Write a flashable image (bin or Intel HEX) of a model for one weight slot.
    Image(cmd::image::Args),
    /// Write a model into the head's idle weight slot through a debug probe (probe-rs).
    Flash(cmd::flash::Args),
    View(cmd::view::Args),
}

fn main() {
    cmd::keep_freed_memory();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Simulate(a) => cmd::simulate::run(a),
        Command::Train(a) => cmd::train::run(a),
        Command::Predict(a) => cmd::predict::run(a),
        Command::Eval(a) => cmd::eval::run(a),
        Command::Info(a) => cmd::info::run(a),
        Command::Demo(a) => cmd::demo::run(a),
        Command::Experiment(a) => cmd::experiment::run(a),
        Command::Render(a) => cmd::render::run(a),
        Command::Track(a) => cmd::track::run(a),
        Command::Board(a) => cmd::board::run(a),
        Command::Collect(a) => cmd::collect::run(a),
        Command::Locate(a) => cmd::locate::run(a),
        Command::Depth(a) => cmd::depth::run(a),
        Command::Emulate(a) => cmd::emulate::run(&a),
        Command::Head(a) => cmd::head::run(&a),
        Command::Image(a) => cmd::image::run(&a),
        Command::Flash(a) => cmd::flash::run(&a),
        Command::View(a) => cmd::view::run(a),
    };
    if let Err(e) = result {
        if is_broken_pipe(&e) {
            // The reader went away (e.g. `hvs predict ... | head`): stop quietly, as `cat` does.
            std::process::exit(141);
        }
        if cmd::is_interrupted(&e) {
            std::process::exit(cmd::exit_code(&e));
        }
        let msg = format!("{e:#}").replace('\n', " ");
        eprintln!("error: {msg}");
        std::process::exit(cmd::exit_code(&e));
    }
}

fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}
