//! `opennav sim`: synthetic data from the simulator.

use std::path::PathBuf;

use clap::Subcommand;

use opennav::perception::detector::parse_prompts;

use super::{bad_input, failed, Failure};

#[derive(Subcommand, Debug)]
pub enum SimCommand {
    /// Writes a synthetic scene in Replica's layout (rendered RGB-D views, traj.txt, ground-truth cloud).
    ReplicaScene {
        /// Dataset root to write.
        #[arg(long)]
        out: PathBuf,
        /// Scene names (comma-separated); each is the same living room.
        #[arg(long, default_value = "office0")]
        scenes: String,
        /// Views along the orbit.
        #[arg(long, default_value_t = 60)]
        views: usize,
        /// Divide the 640×360 frame size by this.
        #[arg(long, default_value_t = 1)]
        scale_down: usize,
    },
}

pub fn run(cmd: SimCommand) -> Result<(), Failure> {
    match cmd {
        SimCommand::ReplicaScene {
            out,
            scenes,
            views,
            scale_down,
        } => {
            if views == 0 {
                return Err(bad_input(anyhow::anyhow!("--views: at least 1")));
            }
            let cam = opennav::sim::replica::camera(scale_down);
            let room = opennav::sim::room::Room::living_room();
            for name in parse_prompts(&scenes) {
                opennav::sim::replica::write_scene(&out, &name, &room, &cam, views)
                    .map_err(failed)?;
                eprintln!(
                    "wrote {} ({views} views, {}x{})",
                    out.join(&name).display(),
                    cam.w,
                    cam.h
                );
            }
            Ok(())
        }
    }
}
