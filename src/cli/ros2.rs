//! `tre ros2`: the ROS 2 node (docs/ros2.md), until Ctrl-C or SIGTERM; its options are
//! [`Ros2Args`].

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use anyhow::Context;
use clap::Args;

use crate::ros2::{self, Ros2Args};

/// Run the ROS 2 node: roughness, uncertainty and three-state images for every frame, and
/// with a pose topic the fused map as grid_map_msgs/GridMap and nav_msgs/OccupancyGrid.
#[derive(Debug, Args)]
pub(crate) struct Ros2 {
    /// The node's topics, map, recording and pipeline.
    #[command(flatten)]
    pub args: Ros2Args,
}

impl Ros2 {
    pub(crate) fn run(self) -> anyhow::Result<()> {
        let a = &self.args;
        // The recording's folder, made as every output folder is.
        if let Some(path) = &a.record {
            crate::io::paths::create_parent(path)?;
        }
        let processor = a.processor()?;
        let node = ros2::start(a.node_config(), processor)?;
        println!(
            "ros2 node {} on domain {} ({}), mode {}: reading {}, publishing under {}",
            a.node_name,
            a.domain_id,
            ros2::COMPILED_ROS_DISTRO,
            a.mode,
            a.input_topic(),
            a.output_prefix
        );
        // ROS messages have no field for an assumption: said here, once.
        for assumed in a.assumption_lines() {
            eprintln!("warning: assumed on every frame: {assumed}");
        }
        self.wait()?;
        let s = node.stats();
        let count = |c: &AtomicU64| c.load(Ordering::Relaxed);
        let line = format!(
            "frames received {}, published {}, dropped (stale) {}, skipped (bad input) {}, fused \
             into the map {}, grid maps made {}, messages refused by the middleware {}",
            count(&s.received),
            count(&s.published),
            count(&s.dropped),
            count(&s.skipped),
            count(&s.fused),
            count(&s.grids),
            count(&s.unsent),
        );
        if let Some(path) = node.stop()? {
            println!("recorded {}", path.display());
        }
        println!("{line}");
        Ok(())
    }

    /// Until Ctrl-C, SIGTERM or `--duration-s`.
    fn wait(&self) -> anyhow::Result<()> {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .context("signal runtime")?;
        rt.block_on(async {
            match self.args.duration_s {
                Some(s) => {
                    tokio::select! {
                        () = tokio::time::sleep(Duration::from_secs_f64(s.max(0.0))) => {},
                        () = crate::server::shutdown_signal() => {},
                    }
                }
                None => crate::server::shutdown_signal().await,
            }
        });
        Ok(())
    }
}
