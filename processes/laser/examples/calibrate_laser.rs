//! Stand-alone `calibrate laser` (the same code `harvest calibrate laser` runs), for measuring:
//! `cargo run -p harvest-laser --release --example calibrate_laser -- --generate`.

use clap::Parser;
use harvest_laser::{CalibrateLaserArgs, run_calibrate_laser};

#[derive(Debug, Parser)]
struct Cli {
    #[command(flatten)]
    args: CalibrateLaserArgs,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let cli = Cli::parse();
    run_calibrate_laser(&cli.args)?;
    Ok(())
}
