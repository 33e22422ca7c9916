//! The `gripsim` command line: thin commands over the library.

use clap::{Parser, Subcommand};
use gripsim::events::{Fanout, Observer};
use gripsim::record::summary::SummaryCollector;
use gripsim::{Scenario, Simulation};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "gripsim",
    version,
    about = "Simulate soft gripper prongs grasping fruit (discrete elastic rods, modified mass contact)",
    after_help = "Examples:\n  gripsim run scenarios/seed-grasp-r5.toml\n  gripsim run scenarios/seed-grasp-r5.toml --set obstacle.0.radius=0.04 --summary out/r4.json\n  gripsim validate scenarios/two-prong-grasp.toml\n  gripsim scenarios"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scenario and print a short summary.
    #[command(
        after_help = "Examples:\n  gripsim run scenarios/seed-grasp-r5.toml\n  gripsim run scenarios/seed-grasp-r5.toml --set rod.0.E=1e9 --summary out/e1gpa.json"
    )]
    Run {
        /// Scenario file (TOML).
        scenario: PathBuf,
        /// Write the run summary as JSON to this file.
        #[arg(long, value_name = "FILE.json")]
        summary: Option<PathBuf>,
        /// Override a scenario value by dotted path, e.g. obstacle.0.radius=0.04 (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        sets: Vec<String>,
        /// Print nothing but errors.
        #[arg(long, short)]
        quiet: bool,
    },
    /// Check a scenario file without running it.
    #[command(
        after_help = "Example:\n  gripsim validate scenarios/seed-grasp-r5.toml --set solve.dt=1e-4"
    )]
    Validate {
        scenario: PathBuf,
        #[arg(long = "set", value_name = "KEY=VALUE")]
        sets: Vec<String>,
    },
    /// List the shipped scenarios with their descriptions.
    #[command(after_help = "Example:\n  gripsim scenarios --dir scenarios")]
    Scenarios {
        #[arg(long, default_value = "scenarios")]
        dir: PathBuf,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Run {
            scenario,
            summary,
            sets,
            quiet,
        } => run(&scenario, summary.as_deref(), &sets, quiet),
        Command::Validate { scenario, sets } => match Scenario::load(&scenario, &sets) {
            Ok(sc) => {
                let nodes: usize = sc.rods.iter().map(|r| r.nodes).sum();
                println!(
                    "{}: ok ({:?}, {} rod(s), {} node(s), {} obstacle(s))",
                    scenario.display(),
                    sc.name,
                    sc.rods.len(),
                    nodes,
                    sc.obstacles.len()
                );
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("error: {e}");
                ExitCode::from(2)
            }
        },
        Command::Scenarios { dir } => list_scenarios(&dir),
    }
}

fn run(path: &Path, summary_path: Option<&Path>, sets: &[String], quiet: bool) -> ExitCode {
    let sc = match Scenario::load(path, sets) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let mut sim = Simulation::new(&sc);
    let mut collector = SummaryCollector::new();
    let start = std::time::Instant::now();
    let result = {
        let mut fan = Fanout::new();
        fan.push(&mut collector as &mut dyn Observer);
        sim.run(&mut fan)
    };
    let wall = start.elapsed().as_secs_f64();
    let summary = collector.finish(&sim.stats, wall);
    if let Some(p) = summary_path {
        let mut text = serde_json::to_string_pretty(&summary).expect("summary serialises");
        text.push('\n');
        if let Err(e) = gripsim::record::write_atomic(p, text.as_bytes()) {
            eprintln!("error: cannot write the summary to {}: {e}", p.display());
            return ExitCode::from(2);
        }
    }
    if !quiet {
        print_summary(&summary);
    }
    match result {
        Ok(_) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

fn print_summary(s: &gripsim::record::summary::Summary) {
    println!("scenario        {}", s.scenario);
    println!(
        "steps           {} ({} Newton iterations, {} corrector passes, {} dt back-offs)",
        s.steps, s.newton_iterations, s.contact_passes, s.dt_backoffs
    );
    println!(
        "simulated       {:.6} s{}",
        s.simulated_time_s,
        if s.mode == "static" {
            " (load factor)"
        } else {
            ""
        }
    );
    println!("wall time       {:.3} s", s.wall_time_s);
    match &s.peak_reaction_node {
        Some(n) => println!(
            "peak reaction   {:.4} N at rod {:?} node {} (t = {:.6} s)",
            s.peak_reaction_force_n,
            n.rod,
            n.node,
            s.peak_reaction_time_s.unwrap_or(0.0)
        ),
        None => println!("peak reaction   none (no contact)"),
    }
    if let Some(t) = s.contact_onset_time_s {
        println!("first contact   t = {t:.6} s");
    }
    println!(
        "penetration     {:.3e} m max after the corrector",
        s.max_penetration_m
    );
    if let Some(n) = &s.max_bending_stress_node {
        println!(
            "bending stress  {:.4e} Pa max at rod {:?} node {}",
            s.max_bending_stress_pa, n.rod, n.node
        );
    }
    for r in &s.rods {
        let tip = r.final_positions.last().copied().unwrap_or([0.0; 2]);
        let busiest = r
            .contact_steps_per_node
            .iter()
            .enumerate()
            .max_by_key(|(i, c)| (**c, std::cmp::Reverse(*i)))
            .filter(|(_, c)| **c > 0);
        print!(
            "rod {:<11} tip at ({:.6}, {:.6}) m",
            format!("{:?}", r.name),
            tip[0],
            tip[1]
        );
        if let Some((i, c)) = busiest {
            print!(", most contact steps: node {i} ({c})");
        }
        println!();
    }
}

fn list_scenarios(dir: &Path) -> ExitCode {
    let mut entries: Vec<PathBuf> = match std::fs::read_dir(dir) {
        Ok(rd) => rd
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect(),
        Err(e) => {
            eprintln!(
                "error: cannot list {}: {e} (run from the project root or pass --dir)",
                dir.display()
            );
            return ExitCode::from(2);
        }
    };
    entries.sort();
    for p in entries {
        match Scenario::load(&p, &[]) {
            Ok(sc) => {
                let first = sc
                    .description
                    .lines()
                    .next()
                    .unwrap_or("")
                    .trim()
                    .to_string();
                println!("{:<44} {}", p.display(), first);
            }
            Err(e) => println!("{:<44} INVALID: {e}", p.display()),
        }
    }
    ExitCode::SUCCESS
}
