//! The SAH constants against speed: builds one SAH kd-tree per `KT/KI/BONUS` (traversal cost,
//! intersection cost, empty bonus) over an OBJ mesh, prints each one's build time and
//! `stats()`, then the single-thread speed of each on the mesh's standard primary, shadow and
//! diffuse rays (median of 5, the trees taking turns).
//!
//! `cargo run --release -p rt-accel-kd --features measure --example kd_costs -- path/to/mesh.obj (or sphere:N, stadium:N) 15/20/0.2 15/7/0.1 [SIDE]`
//! (`SIDE`: camera resolution, default 512).

use rt_accel_kd::{KdParams, KdTree};
use rt_geom::Triangle;
use rt_testkit::RaySets;

fn parse_costs(s: &str) -> Option<KdParams> {
    let v: Vec<f32> = s
        .split('/')
        .map(|x| x.parse().ok())
        .collect::<Option<_>>()?;
    let [kt, ki, bonus] = v[..] else { return None };
    Some(KdParams {
        traversal_cost: kt,
        intersection_cost: ki,
        empty_bonus: bonus,
        ..KdParams::sah()
    })
}

fn main() {
    RaySets::race_configs(
        "usage: kd_costs MESH.obj KT/KI/BONUS... [SIDE]",
        parse_costs,
        |tris: &[Triangle], params| KdTree::build(tris, *params),
    );
}
