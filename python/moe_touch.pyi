"""MOE-Touch: contact from a soft hand's deformation, numpy in and out.

Arrays are float64 in metres and newtons unless said; per-finger values are lists with one
array per finger. Every failure of the Rust code raises MoeTouchError (a ValueError) with the
line the moe-touch tool prints for the same error; wrong types are TypeError, an index past the
end IndexError. Long calls release the GIL.
"""

from os import PathLike
from typing import Any, Iterator, Literal, Optional, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Path = Union[str, PathLike[str]]
_F64 = npt.NDArray[np.float64]
_F32 = npt.NDArray[np.float32]
_U8 = npt.NDArray[np.uint8]
_U32 = npt.NDArray[np.uint32]
_Ints = npt.ArrayLike

class MoeTouchError(ValueError):
    """A failure of MOE-Touch: bad input, an unreadable file, a failing stage."""

class Hand:
    """A soft multi-finger hand: rest surfaces, markers, tendons, finger placement."""

    @staticmethod
    def preset(name: Literal["two-finger", "three-finger", "five-finger"]) -> Hand: ...
    @staticmethod
    def from_file(path: _Path) -> Hand: ...
    @staticmethod
    def load(spec: str) -> Hand:
        """A preset name or a hand config file, as the tool's --hand takes it."""
    @property
    def name(self) -> str: ...
    @property
    def num_fingers(self) -> int: ...
    @property
    def tendons_per_finger(self) -> int: ...
    @property
    def num_vertices(self) -> int: ...
    def rest_vertices(self, finger: int) -> _F64:
        """(n, 3), hand frame."""
    def faces(self, finger: int) -> _U32:
        """(m, 3) vertex indices."""
    def marker_vertices(self, finger: int) -> _U32: ...
    def hand_from_finger(self, finger: int) -> _F64:
        """4 x 4."""
    def rest_keypoints(self) -> list[_F64]:
        """(markers, 3) per finger, hand frame."""

class Camera:
    """The wrist camera: pinhole intrinsics of the colour image and its mounting on the hand."""

    def __init__(
        self,
        width: int,
        height: int,
        fx: float,
        fy: float,
        cx: float,
        cy: float,
        hand_from_camera: _F64,
    ) -> None: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def intrinsics(self) -> tuple[float, float, float, float]:
        """(fx, fy, cx, cy), pixels."""
    @property
    def hand_from_camera(self) -> _F64: ...

class ArapSolver:
    """SR-ARAP on a triangle mesh, factorised once for its fixed and handle vertices."""

    def __init__(
        self,
        vertices: _F64,
        faces: _Ints,
        fixed: _Ints,
        handles: _Ints,
        *,
        alpha: Optional[float] = None,
        iterations: Optional[int] = None,
    ) -> None: ...
    def solve(
        self, fixed_targets: _F64, handle_targets: _F64, start: Optional[_F64] = None
    ) -> _F64:
        """(n, 3); a NaN row of handle_targets leaves that handle free."""
    @property
    def num_vertices(self) -> int: ...
    @property
    def num_parts(self) -> int: ...

class ShapeEstimator:
    """The hand's shape from its markers by SR-ARAP (markers as handles, bases fixed)."""

    def __init__(
        self, hand: Hand, *, iterations: Optional[int] = None, warm_start: bool = False
    ) -> None: ...
    def estimate(self, keypoints: list[_F64]) -> list[_F64]:
        """(markers, 3) per finger (NaN rows: not seen) -> (n, 3) per finger."""

class ContactModel:
    """A trained contact network (NAME.safetensors with its card NAME.json)."""

    def __init__(self, path: _Path, hand: Hand) -> None: ...
    @property
    def threshold(self) -> float: ...
    @property
    def card(self) -> dict[str, Any]: ...
    def estimate(self, vertices: list[_F64], pulls: Optional[_F64] = None) -> list[_F64]:
        """(n, 3) per finger -> contact probability (n,) per finger."""

class PhysicsResult:
    """What the physics estimator found (hand frame, metres, newtons)."""

    @property
    def vertices(self) -> list[_F64]:
        """(n, 3) per finger: the dented surface."""
    @property
    def contact_probability(self) -> list[_F64]: ...
    @property
    def vertex_force(self) -> list[_F64]: ...
    @property
    def finger_force(self) -> _F64:
        """(fingers, 3)."""
    @property
    def pressed_probability(self) -> _F64: ...
    @property
    def loads(self) -> list[dict[str, Any]]: ...
    @property
    def finger_errors(self) -> list[Optional[str]]: ...

class PhysicsEstimator:
    """The finger's FEM model read backwards from its markers (no camera)."""

    def __init__(
        self, hand: Hand, *, material: Optional[_Path] = None, config: Optional[_Path] = None
    ) -> None: ...
    def estimate(
        self,
        keypoints: list[_F64],
        pulls: _F64,
        world_from_hand: Optional[_F64] = None,
        time: Optional[float] = None,
    ) -> PhysicsResult:
        """keypoints (markers, 3) per finger (NaN: not seen), pulls (fingers, tendons)."""
    def reset(self) -> None: ...
    @property
    def threshold(self) -> float: ...

class Timings:
    """Wall time of each stage of one frame, milliseconds."""

    @property
    def markers_ms(self) -> float: ...
    @property
    def estimate_ms(self) -> float: ...
    @property
    def points_ms(self) -> float: ...
    @property
    def total_ms(self) -> float: ...

class FrameResult:
    """Everything the pipeline estimated about one frame."""

    @property
    def keypoints(self) -> list[_F64]:
        """(markers, 3) per finger, hand frame, NaN where not seen."""
    @property
    def vertices(self) -> list[_F64]:
        """(n, 3) per finger, hand frame."""
    @property
    def contact_probability(self) -> list[_F64]:
        """(n,) per finger."""
    @property
    def vertex_force(self) -> Optional[list[_F64]]:
        """(n, 3) per finger, hand frame, newtons (physics)."""
    @property
    def finger_force(self) -> Optional[_F64]:
        """(fingers, 3): the net force the world exerts on each finger (physics)."""
    @property
    def pressed_probability(self) -> Optional[_F64]:
        """(fingers,) (physics)."""
    @property
    def loads(self) -> list[dict[str, Any]]:
        """Loads found (physics): finger, vertex, location_rest, location, force, magnitude,
        magnitude_sd, location_sd_along, location_sd_around."""
    @property
    def contacts_hand(self) -> _F64:
        """(k, 3) contact points, hand frame."""
    @property
    def contacts_world(self) -> _F64:
        """(k, 3) contact points, world frame."""
    @property
    def contact_finger(self) -> _U32: ...
    @property
    def contact_vertex(self) -> _U32: ...
    @property
    def contact_point_probability(self) -> _F64: ...
    @property
    def num_contacts(self) -> int: ...
    @property
    def markers_found(self) -> int: ...
    @property
    def fingers_without_markers(self) -> list[int]: ...
    @property
    def world_from_hand(self) -> _F64: ...
    @property
    def timings(self) -> Timings: ...
    @property
    def stream(self) -> Literal["untimed", "started", "continued", "restarted"]: ...
    @property
    def gap_secs(self) -> Optional[float]: ...

class Pipeline:
    """Markers, shape, contact and force from wrist RGB-D frames."""

    @staticmethod
    def physics(
        hand: Hand,
        camera: Camera,
        *,
        material: Optional[_Path] = None,
        config: Optional[_Path] = None,
        detector: Optional[_Path] = None,
    ) -> Pipeline:
        """The physics estimator (the tool's default): contact and force, no model."""
    @staticmethod
    def dgcnn(
        hand: Hand,
        camera: Camera,
        model: _Path,
        *,
        iterations: Optional[int] = None,
        warm_start: bool = False,
        detector: Optional[_Path] = None,
    ) -> Pipeline:
        """The paper's pipeline: SR-ARAP shape, then the trained network."""
    def process(
        self,
        color: _U8,
        depth: _F32,
        world_from_hand: _F64,
        pulls: Optional[_F64] = None,
        time: Optional[float] = None,
    ) -> FrameResult:
        """color (h, w, 3) uint8 RGB, depth (h, w) float32 metres, world_from_hand 4 x 4,
        pulls (fingers, tendons) metres, time seconds (memory across frames)."""
    def reset(self) -> None: ...
    @property
    def threshold(self) -> float: ...
    @property
    def method(self) -> Literal["physics", "dgcnn"]: ...

class EpisodeFrame:
    """One recorded frame; the true_* fields exist for simulated episodes."""

    @property
    def time_ns(self) -> int: ...
    @property
    def time(self) -> float: ...
    @property
    def color(self) -> _U8: ...
    @property
    def depth(self) -> _F32: ...
    @property
    def world_from_hand(self) -> _F64: ...
    @property
    def pulls(self) -> _F64: ...
    @property
    def true_vertices(self) -> Optional[list[_F64]]: ...
    @property
    def true_contact_vertices(self) -> Optional[list[_U32]]: ...
    @property
    def true_markers(self) -> Optional[list[_F64]]: ...

class Episode:
    """A recorded episode: the camera, the hand's layout and the frames."""

    @property
    def scene(self) -> str: ...
    @property
    def camera(self) -> Camera: ...
    @property
    def num_fingers(self) -> int: ...
    @property
    def tendons_per_finger(self) -> int: ...
    @property
    def truncated(self) -> Optional[str]: ...
    @property
    def frames(self) -> list[EpisodeFrame]: ...
    def __len__(self) -> int: ...
    def __getitem__(self, index: int) -> EpisodeFrame: ...
    def __iter__(self) -> Iterator[EpisodeFrame]: ...

class Dataset:
    """A data set written by `moe-touch gen-data`."""

    def __init__(self, path: _Path) -> None: ...
    @property
    def card(self) -> dict[str, Any]: ...
    @property
    def num_shards(self) -> int: ...
    def __len__(self) -> int: ...
    def shard(self, index: int) -> dict[str, Optional[npt.NDArray[Any]]]: ...
    def frames(
        self, split: Optional[Literal["train", "validation", "test"]] = None
    ) -> DatasetFrames: ...

class DatasetFrames:
    def __iter__(self) -> DatasetFrames: ...
    def __next__(self) -> dict[str, Any]:
        """One frame: arrays, and numpy scalars for the per-frame numbers."""

def read_episode(
    path: _Path, hand: Optional[Hand] = None, ros: Union[_Path, dict[str, Any], None] = None
) -> Episode:
    """The simulator's MCAP episode, or a ROS 2 recording (rosbag2 directory or MCAP file)."""

def read_ros2_bag(
    path: _Path, hand: Optional[Hand] = None, ros: Union[_Path, dict[str, Any], None] = None
) -> Episode: ...
def is_ros2_recording(path: _Path) -> bool: ...
