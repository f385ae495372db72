//! Stand-alone `eval laser` (the same code `harvest eval laser` runs), for measuring:
//! `cargo run -p harvest-laser --release --example eval_laser -- --worlds 10`.

use clap::Parser;
use harvest_laser::{EvalLaserArgs, run_eval_laser};

#[derive(Debug, Parser)]
struct Cli {
    #[command(flatten)]
    args: EvalLaserArgs,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cli = Cli::parse();
    run_eval_laser(&cli.args)?;
    Ok(())
}
