"""The README's Python example: the physics pipeline over the committed demo episode (a plate
pressing a fingertip), run from the repository's root: `python python/examples/quickstart.py`. It prints what the
Rust example (`examples/quickstart`, `cargo run -p moe-touch-quickstart`) prints.
"""

import moe_touch as mt

episode = mt.read_episode("fixtures/episodes/plate_tip_front_small.mcap")  # or a ROS 2 bag
hand = mt.Hand.preset("two-finger")  # or mt.Hand.from_file("my-hand.toml")
pipeline = mt.Pipeline.physics(
    hand, episode.camera, config="fixtures/physics/occluding-contact.toml"
)
for frame in episode:
    r = pipeline.process(
        frame.color, frame.depth, frame.world_from_hand, frame.pulls, time=frame.time
    )
    forces_mn = ", ".join(f"{1e3 * float(f @ f) ** 0.5:.1f}" for f in r.finger_force_n)
    print(f"{frame.time:.2f} s: {r.markers_found} markers, {r.num_contacts} contact points, "
          f"finger forces [{forces_mn}] mN")
