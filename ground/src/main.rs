//! `ground`: the MMIC-I operators' tool. See `docs/operator-guide.md`.
//!
//! Exit codes (the table in docs/operator-guide.md): 0 success; 1 error (I/O, archive,
//! internal); 2 command-line usage; 3 invalid input or refused before sending (plan, TC
//! name or arguments, an unconfirmed hazardous TC, corrupt packets with
//! `decode --strict`); 4 a TC or plan step failed, was refused or timed out; 5 a robot
//! heard, then lost (link lost; also: no simulator answering); 6 a run interrupted by the
//! operator; 7 replies from another APID (wrong robot at the address); 8 nothing heard
//! from a robot; 130 a second Ctrl-C.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Parser, Subcommand};

mod demo;
mod exit;
mod links;
mod output;
mod plot;
mod verb_archive;
mod verb_collect;
mod verb_decode;
mod verb_file;
mod verb_keys;
mod verb_live;
mod verb_mib;
mod verb_model;
mod verb_plan;
mod verb_run;
mod verb_sim;
mod verb_update;

use verb_archive::{archive_cmd, ArchiveCmd};
use verb_decode::{decode, DecodeArgs};
use verb_live::{mode, ping, send, watch, ModeArgs, PingArgs, SendArgs, WatchArgs};
use verb_mib::{mib_export, MibCmd};
use verb_model::{model, ModelArgs};
use verb_plan::{plan_check, plan_control, plan_encode, PlanCmd};
use verb_run::{run_plan, RunArgs};
use verb_sim::{sim, SimArgs};

use exit::Coded;
use output::err_line;

#[derive(Parser, Debug)]
#[command(name = "ground", version, about = "MMIC-I ground tool: plans, live operations, TM decode and archive", long_about = None)]
struct Cli {
    /// Archive written by run, send, ping, mode, watch and demo: an SQLite file, or a
    /// PostgreSQL server as `postgresql://USER@HOST/DB` (see docs/archive.md).
    #[arg(long, global = true, default_value = "ground-archive.db")]
    archive: PathBuf,
    /// Do not write the archive.
    #[arg(long, global = true)]
    no_archive: bool,
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Check or encode plan files; suspend, resume, abort, skip or report a robot's
    /// on-board plan.
    #[command(subcommand)]
    Plan(PlanCmd),
    /// Decode a file of TC and/or TM space packets.
    Decode(DecodeArgs),
    /// Execute a plan against running OBSWs.
    Run(RunArgs),
    /// Connection test (TC[17,1]) to each robot.
    Ping(PingArgs),
    /// Send one TC by its MIB name, e.g. `ground send --robot 1 RECONFIGURE from=0 to=4`.
    Send(SendArgs),
    /// Command a robot's mode (standby, operational, safed).
    Mode(ModeArgs),
    /// Show live decoded TM and events.
    Watch(WatchArgs),
    /// Send a fault-injection line to a simulator's control port.
    Sim(SimArgs),
    /// Query, export or plot the archive.
    #[command(subcommand)]
    Archive(ArchiveCmd),
    /// Export the MIB for other ground systems.
    #[command(subcommand)]
    Mib(MibCmd),
    /// Write a robot's URDF from its module report (live) or a module-set file.
    Model(ModelArgs),
    /// Start two simulated robots, run the demo plan and summarise.
    Demo(demo::DemoArgs),
    /// Follow robots unattended: archive everything, fill gaps, raise alarms.
    Collect(verb_collect::CollectArgs),
    /// List, acknowledge or shelve the collector's alarms.
    #[command(subcommand)]
    Alarms(verb_collect::AlarmsCmd),
    /// Create or show the space link's key files (never prints a key).
    #[command(subcommand)]
    Keys(verb_keys::KeysCmd),
    /// Files to and from a robot's file store over CFDP: put, get, ls, rm, mv.
    #[command(subcommand)]
    File(verb_file::FileCmd),
    /// Software update: keygen, sign, install (into the inactive slot), activate.
    #[command(subcommand)]
    Update(verb_update::UpdateCmd),
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
    };
    match run(cli) {
        Ok(code) => ExitCode::from(code),
        Err(e) => {
            if is_broken_pipe(&e) {
                return ExitCode::from(exit::OK);
            }
            let code = e.downcast_ref::<Coded>().map_or(exit::ERROR, |c| c.0);
            err_line!("ground: error: {e:#}");
            ExitCode::from(code)
        }
    }
}

fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

fn run(cli: Cli) -> Result<u8> {
    let archive_path = (!cli.no_archive).then(|| cli.archive.clone());
    match cli.cmd {
        Cmd::Plan(PlanCmd::Check { plans, json }) => plan_check(&plans, json),
        Cmd::Plan(PlanCmd::Encode { plan, out: dir }) => plan_encode(&plan, &dir),
        Cmd::Plan(c) => plan_control(&c, archive_path.as_deref()),
        Cmd::Decode(a) => decode(&a),
        Cmd::Run(a) => run_plan(&a, archive_path.as_deref()),
        Cmd::Ping(a) => ping(&a, archive_path.as_deref()),
        Cmd::Send(a) => send(&a, archive_path.as_deref()),
        Cmd::Mode(a) => mode(&a, archive_path.as_deref()),
        Cmd::Watch(a) => watch(&a, archive_path.as_deref()),
        Cmd::Sim(a) => sim(&a),
        Cmd::Archive(a) => archive_cmd(a, &cli.archive),
        Cmd::Mib(MibCmd::Export { format, out: dir }) => mib_export(&format, &dir),
        Cmd::Model(a) => model(&a, archive_path.as_deref()),
        Cmd::Demo(a) => demo::demo(&a, archive_path.as_deref()),
        Cmd::Collect(a) => verb_collect::collect(&cli.archive, a),
        Cmd::Alarms(a) => verb_collect::alarms(&cli.archive, a),
        Cmd::Keys(a) => verb_keys::keys(&a),
        Cmd::File(a) => verb_file::file(&a),
        Cmd::Update(a) => verb_update::update(&a),
    }
}
