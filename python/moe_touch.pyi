"""MOE-Touch: contact from a soft hand's deformation, numpy in and out.

Arrays are float64 in metres and newtons unless said; per-finger values are lists with one
array per finger. Every failure of the Rust code raises a MoeTouchError with the line the
moe-touch tool prints for the same error: MoeTouchFileNotFoundError (also a FileNotFoundError)
for a missing file, MoeTouchOSError (an OSError) for another failure to read one,
MoeTouchValueError (a ValueError) for bad values, malformed input or a failing stage. Wrong
types are TypeError, an index past the end IndexError. Long calls release the GIL.
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
_Settings = Union[_Path, dict[str, Any], None]

class MoeTouchError(Exception):
    """A failure of MOE-Touch; raised as one of the three subclasses below."""

class MoeTouchOSError(MoeTouchError, OSError):
    """The operating system refused to read a file."""

class MoeTouchFileNotFoundError(MoeTouchOSError, FileNotFoundError):
    """A file MOE-Touch was asked to read does not exist."""

class MoeTouchValueError(MoeTouchError, ValueError):
    """Bad values or malformed input (a file that does not parse, an unknown setting) or a
    failing stage."""

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

class MultiShapeEstimator:
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
    def card(self) -> ModelCard: ...
    def estimate(self, vertices: list[_F64], pulls: Optional[_F64] = None) -> list[_F64]:
        """(n, 3) per finger -> contact probability (n,) per finger."""

class CardHand:
    """The hand a model was trained for."""

    @property
    def name(self) -> str: ...
    @property
    def finger_num_vertices(self) -> list[int]: ...
    @property
    def finger_digests(self) -> list[str]:
        """Digest of each finger's rest mesh (empty in old cards)."""

class CardTraining:
    """How a model's weights were trained."""

    @property
    def command(self) -> str: ...
    @property
    def config(self) -> dict[str, Any]:
        """The training settings (optimiser, schedule, loss, seed), raw."""
    @property
    def contact_weight(self) -> float: ...
    @property
    def init(self) -> Optional[str]: ...
    @property
    def input_shape(self) -> str: ...
    @property
    def marker_noise_m(self) -> float: ...
    @property
    def marker_dropout(self) -> float: ...
    @property
    def marker_tip_occlusion(self) -> float: ...
    @property
    def marker_tip_run(self) -> int: ...
    @property
    def sets_per_second(self) -> float: ...
    @property
    def train_seconds(self) -> float: ...
    @property
    def train_sets(self) -> int: ...
    @property
    def validation_sets(self) -> int: ...
    @property
    def wall_time_s(self) -> float: ...

class CardDataSource:
    """One data set a model was trained on."""

    @property
    def dir(self) -> str: ...
    @property
    def seed(self) -> int: ...
    @property
    def frames(self) -> int: ...
    @property
    def trajectories(self) -> int: ...
    @property
    def label_rule(self) -> str: ...
    @property
    def regenerate(self) -> str: ...
    @property
    def generator(self) -> dict[str, Any]: ...

class CardDataset:
    """The data a model was trained on."""

    @property
    def sets(self) -> list[CardDataSource]: ...
    @property
    def train_frames(self) -> int: ...
    @property
    def validation_frames(self) -> int: ...

class EpochRecord:
    """One training epoch measured on the validation frames (NaN: not defined)."""

    @property
    def epoch(self) -> int: ...
    @property
    def learning_rate(self) -> float: ...
    @property
    def train_loss(self) -> float: ...
    @property
    def validation_loss(self) -> float: ...
    @property
    def validation_threshold(self) -> float: ...
    @property
    def validation_f1(self) -> float: ...
    @property
    def validation_precision(self) -> float: ...
    @property
    def validation_recall(self) -> float: ...
    @property
    def validation_iou(self) -> float: ...
    @property
    def validation_f1_at_half(self) -> float: ...
    @property
    def validation_contact_bcd_mm(self) -> float: ...
    @property
    def validation_miss_rate(self) -> float: ...
    @property
    def validation_false_alarm_rate(self) -> float: ...
    @property
    def seconds(self) -> float: ...

class CardMetrics:
    """A model's learning curve."""

    @property
    def epochs(self) -> list[EpochRecord]: ...

class ModelCard:
    """A contact model's card: what the weights are and how they were made."""

    @property
    def format_version(self) -> int: ...
    @property
    def threshold(self) -> float: ...
    @property
    def features(self) -> list[str]:
        """The input feature groups in channel order."""
    @property
    def architecture(self) -> dict[str, Any]:
        """The network's settings, raw."""
    @property
    def hand(self) -> Optional[CardHand]: ...
    @property
    def training(self) -> Optional[CardTraining]: ...
    @property
    def dataset(self) -> Optional[CardDataset]: ...
    @property
    def metrics(self) -> Optional[CardMetrics]: ...
    def to_dict(self) -> dict[str, Any]:
        """The card as its JSON file holds it."""

class ContactLoad:
    """One load the physics estimator found (hand frame, metres, newtons)."""

    @property
    def finger(self) -> int: ...
    @property
    def vertex(self) -> int: ...
    @property
    def location_rest(self) -> _F64:
        """(3,): the load's place on the rest surface."""
    @property
    def location(self) -> _F64:
        """(3,): the same point on the estimated surface."""
    @property
    def force(self) -> _F64:
        """(3,) newtons: the force the world exerts on the finger."""
    @property
    def magnitude(self) -> float: ...
    @property
    def magnitude_sd(self) -> float: ...
    @property
    def location_sd_along(self) -> Optional[float]: ...
    @property
    def location_sd_around(self) -> Optional[float]: ...
    @property
    def patch(self) -> list[tuple[int, float]]:
        """(vertex, share of the force) pairs."""

class PhysicsEstimate:
    """What the physics estimator found (hand frame, metres, newtons)."""

    @property
    def shape(self) -> list[_F64]:
        """(n, 3) per finger: the dented surface."""
    @property
    def contact(self) -> list[_F64]:
        """(n,) per finger: contact probability."""
    @property
    def vertex_force_n(self) -> list[_F64]: ...
    @property
    def finger_force_n(self) -> _F64:
        """(fingers, 3)."""
    @property
    def pressed_probability(self) -> _F64: ...
    @property
    def loads(self) -> list[ContactLoad]: ...
    @property
    def finger_errors(self) -> list[Optional[str]]: ...
    @property
    def solves(self) -> list[int]:
        """Per finger: the linear solves of the frame."""
    @property
    def degraded(self) -> list[bool]:
        """Per finger: whether the load search stopped short of its converged answer (the
        frame's budget spent, or a proposed load of which the model could carry no part)."""

class PhysicsEstimator:
    """The finger's FEM model read backwards from its markers (no camera)."""

    def __init__(
        self, hand: Hand, *, material: _Settings = None, config: _Settings = None
    ) -> None:
        """material (HandMaterial) and config (PhysicsConfig): a TOML or JSON file or a dict."""
    def estimate(
        self,
        keypoints: list[_F64],
        pulls: _F64,
        world_from_hand: Optional[_F64] = None,
        time: Optional[float] = None,
    ) -> PhysicsEstimate:
        """keypoints (markers, 3) per finger (NaN: not seen), pulls (fingers, tendons)."""
    def reset(self) -> None: ...
    @property
    def threshold(self) -> float: ...

class StageTimings:
    """Wall time of each stage of one frame, milliseconds."""

    @property
    def markers_ms(self) -> float: ...
    @property
    def estimate_ms(self) -> float: ...
    @property
    def points_ms(self) -> float: ...
    @property
    def total_ms(self) -> float: ...

class FrameEstimate:
    """Everything the pipeline estimated about one frame."""

    @property
    def keypoints(self) -> list[_F64]:
        """(markers, 3) per finger, hand frame, NaN where not seen."""
    @property
    def shape(self) -> list[_F64]:
        """(n, 3) per finger, hand frame: the estimated surface."""
    @property
    def contact(self) -> list[_F64]:
        """(n,) per finger: contact probability."""
    @property
    def vertex_force_n(self) -> Optional[list[_F64]]:
        """(n, 3) per finger, hand frame, newtons (physics)."""
    @property
    def finger_force_n(self) -> Optional[_F64]:
        """(fingers, 3): the net force the world exerts on each finger (physics)."""
    @property
    def pressed_probability(self) -> Optional[_F64]:
        """(fingers,) (physics)."""
    @property
    def loads(self) -> list[ContactLoad]:
        """Loads found (physics; empty otherwise)."""
    @property
    def contacts_in_hand(self) -> _F64:
        """(k, 3) contact points, hand frame."""
    @property
    def contacts_in_world(self) -> _F64:
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
    def timings(self) -> StageTimings: ...
    @property
    def stream(
        self,
    ) -> Literal["untimed", "started", "continued", "restarted", "recovered"]: ...
    @property
    def gap_secs(self) -> Optional[float]: ...

class Pipeline:
    """Markers, shape, contact and force from wrist RGB-D frames."""

    @staticmethod
    def physics(
        hand: Hand,
        camera: Camera,
        *,
        material: _Settings = None,
        config: _Settings = None,
        detector: _Settings = None,
    ) -> Pipeline:
        """The physics estimator (the tool's default): contact and force, no model. material
        (HandMaterial), config (PhysicsConfig), detector (DetectorConfig): each a TOML or JSON
        file or a dict of the settings; unknown keys raise MoeTouchValueError."""
    @staticmethod
    def paper(
        hand: Hand,
        camera: Camera,
        model: _Path,
        *,
        iterations: Optional[int] = None,
        warm_start: bool = False,
        shape: _Settings = None,
        detector: _Settings = None,
    ) -> Pipeline:
        """The paper's pipeline: SR-ARAP shape, then the trained network."""
    def process(
        self,
        color: _U8,
        depth: _F32,
        world_from_hand: _F64,
        pulls: Optional[_F64] = None,
        time: Optional[float] = None,
    ) -> FrameEstimate:
        """color (h, w, 3) uint8 RGB, depth (h, w) float32 metres, world_from_hand 4 x 4,
        pulls (fingers, tendons) metres, time seconds (memory across frames).

        A frame that cannot be estimated raises the MoeTouchError of its kind with the
        frame's status as attributes: stage ("input", "markers", "estimate" or "contact
        points"), keypoints (per finger, the markers found, NaN where unseen; None when
        perception did not run), markers_found, stream and gap_secs (None for a frame refused
        before it entered the stream). The pipeline stays usable: the next frame goes on
        from the stream's memory, or after a failed estimate from an estimator at rest
        (stream "recovered")."""
    def reset(self) -> None: ...
    @property
    def threshold(self) -> float: ...
    @property
    def method(self) -> Literal["physics", "dgcnn"]:
        """The tool's --contact for this pipeline (Pipeline.paper: "dgcnn")."""

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

class FrameStats:
    """Counts over a set of frames."""

    @property
    def frames(self) -> int: ...
    @property
    def trajectories(self) -> int: ...
    @property
    def contact_frames(self) -> int: ...
    @property
    def contact_vertices(self) -> int: ...
    @property
    def vertices(self) -> int: ...
    @property
    def force_frames(self) -> int: ...
    @property
    def contact_ratio(self) -> float: ...

class ShardEntry:
    """One shard as a data set's card lists it."""

    @property
    def file(self) -> str: ...
    @property
    def stats(self) -> FrameStats: ...

class DatasetLayout:
    """The frame layout of a data set."""

    @property
    def finger_num_vertices(self) -> list[int]: ...
    @property
    def markers_per_finger(self) -> list[int]: ...
    @property
    def tendons_per_finger(self) -> int: ...
    @property
    def object_param_len(self) -> int: ...
    @property
    def object_families(self) -> list[str]: ...

class DatasetCard:
    """A data set's card.json: layout, seed, generator, shards and frame counts."""

    @property
    def format_version(self) -> int: ...
    @property
    def layout(self) -> DatasetLayout: ...
    @property
    def seed(self) -> int: ...
    @property
    def generator(self) -> dict[str, Any]: ...
    @property
    def shards(self) -> list[ShardEntry]: ...
    @property
    def totals(self) -> FrameStats: ...
    @property
    def families(self) -> dict[str, FrameStats]: ...
    def to_dict(self) -> dict[str, Any]:
        """The card as its card.json holds it."""

class Dataset:
    """A data set written by `moe-touch gen-data`."""

    def __init__(self, path: _Path) -> None: ...
    @property
    def card(self) -> DatasetCard: ...
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

def read_episode(path: _Path, hand: Optional[Hand] = None, ros: _Settings = None) -> Episode:
    """The simulator's MCAP episode, or a ROS 2 recording (rosbag2 directory or MCAP file)."""

def read_ros2_bag(path: _Path, hand: Optional[Hand] = None, ros: _Settings = None) -> Episode: ...
def is_ros2_recording(path: _Path) -> bool: ...
