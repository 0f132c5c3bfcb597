"""An independent ROS 2 peer for tests/ros2_interop.rs: Eclipse Cyclone DDS
(its Python binding) with the ROS 2 type names and the `rt/` prefix, the
message layouts written here from the ROS 2 `.msg` files. It says "chair"
on /opennav/prompt until the chair answers, then listens to every topic of
the bridge until "Arrived at the chair." or the time limit; prints one JSON
object: what it heard."""
import json
import math
import sys
import time
from dataclasses import dataclass

from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication, BuiltinTopicDcpsSubscription
from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct, types
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration


@dataclass
class String_(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    data: str


@dataclass
class Time_(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: types.int32
    nanosec: types.uint32


@dataclass
class Header_(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time_
    frame_id: str


@dataclass
class LaserScan_(IdlStruct, typename="sensor_msgs::msg::dds_::LaserScan_"):
    header: Header_
    angle_min: types.float32
    angle_max: types.float32
    angle_increment: types.float32
    time_increment: types.float32
    scan_time: types.float32
    range_min: types.float32
    range_max: types.float32
    ranges: types.sequence[types.float32]
    intensities: types.sequence[types.float32]


@dataclass
class Vector3_(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: types.float64
    y: types.float64
    z: types.float64


@dataclass
class Point_(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: types.float64
    y: types.float64
    z: types.float64


@dataclass
class Quaternion_(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: types.float64
    y: types.float64
    z: types.float64
    w: types.float64


@dataclass
class Pose_(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point_
    orientation: Quaternion_


@dataclass
class PoseWithCovariance_(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose_
    covariance: types.array[types.float64, 36]


@dataclass
class Twist_(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3_
    angular: Vector3_


@dataclass
class TwistWithCovariance_(IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"):
    twist: Twist_
    covariance: types.array[types.float64, 36]


@dataclass
class Odometry_(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header_
    child_frame_id: str
    pose: PoseWithCovariance_
    twist: TwistWithCovariance_


@dataclass
class Transform_(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3_
    rotation: Quaternion_


@dataclass
class TransformStamped_(IdlStruct, typename="geometry_msgs::msg::dds_::TransformStamped_"):
    header: Header_
    child_frame_id: str
    transform: Transform_


@dataclass
class TFMessage_(IdlStruct, typename="tf2_msgs::msg::dds_::TFMessage_"):
    transforms: types.sequence[TransformStamped_]


@dataclass
class ObjectHypothesis_(IdlStruct, typename="vision_msgs::msg::dds_::ObjectHypothesis_"):
    class_id: str
    score: types.float64


@dataclass
class ObjectHypothesisWithPose_(IdlStruct, typename="vision_msgs::msg::dds_::ObjectHypothesisWithPose_"):
    hypothesis: ObjectHypothesis_
    pose: PoseWithCovariance_


@dataclass
class BoundingBox3D_(IdlStruct, typename="vision_msgs::msg::dds_::BoundingBox3D_"):
    center: Pose_
    size: Vector3_


@dataclass
class Detection3D_(IdlStruct, typename="vision_msgs::msg::dds_::Detection3D_"):
    header: Header_
    results: types.sequence[ObjectHypothesisWithPose_]
    bbox: BoundingBox3D_
    id: str


@dataclass
class Detection3DArray_(IdlStruct, typename="vision_msgs::msg::dds_::Detection3DArray_"):
    header: Header_
    detections: types.sequence[Detection3D_]


limit = float(sys.argv[1]) if len(sys.argv) > 1 else 60.0
SPACING_S = float(sys.argv[2]) if len(sys.argv) > 2 else 0.1
dp = DomainParticipant(0)
prompt = DataWriter(dp, Topic(dp, "rt/opennav/prompt", String_))
time.sleep(SPACING_S)
stop = DataWriter(dp, Topic(dp, "rt/opennav/stop", String_))
time.sleep(SPACING_S)


def reader(name, kind, qos=None):
    # endpoints made one by one: RustDDS 0.11.4 misses some of a peer's
    # endpoints announced in one burst (see src/ros2/bridge.rs)
    r = DataReader(dp, Topic(dp, name, kind), qos=qos)
    time.sleep(SPACING_S)
    return r


latched = Qos(
    Policy.Reliability.Reliable(duration(seconds=1)),
    Policy.Durability.TransientLocal,
    Policy.History.KeepLast(1),
)
said = reader("rt/opennav/said", String_)
state = reader("rt/opennav/state", String_)
scans = {"left": reader("rt/scan_left", LaserScan_), "right": reader("rt/scan_right", LaserScan_)}
odom = reader("rt/odom", Odometry_)
tf = reader("rt/tf", TFMessage_)
tf_static = reader("rt/tf_static", TFMessage_, latched)
objects = reader("rt/opennav/objects", Detection3DArray_)
tracks = reader("rt/opennav/tracks", Detection3DArray_)

# the chair's endpoints, as DDS announces them: wait for every one before
# saying the word (RustDDS repairs a late joiner's missed announcements
# slowly), and say how long that took
WRITERS = {"rt/opennav/said", "rt/opennav/state", "rt/scan_left", "rt/scan_right", "rt/odom",
           "rt/tf", "rt/tf_static", "rt/opennav/objects", "rt/opennav/tracks"}
READERS = {"rt/opennav/prompt", "rt/opennav/stop"}
publications = BuiltinDataReader(dp, BuiltinTopicDcpsPublication)
subscriptions = BuiltinDataReader(dp, BuiltinTopicDcpsSubscription)
started = time.time()
seen_writers, seen_readers = set(), set()
while time.time() < started + limit / 2:
    seen_writers |= {s.topic_name for s in publications.take(N=100)} & WRITERS
    seen_readers |= {s.topic_name for s in subscriptions.take(N=100)} & READERS
    if seen_writers == WRITERS and seen_readers == READERS:
        break
    time.sleep(0.05)
discovery_s = time.time() - started

heard, states = [], []
out = {
    "discovery_s": discovery_s,
    "unseen": sorted((WRITERS - seen_writers) | (READERS - seen_readers)),
    "scans": {"left": 0, "right": 0},
    "scan": None,
    "odom": 0,
    "odom_last": None,
    "tf": [],
    "tf_static": [],
    "objects": 0,
    "object_labels": [],
    "track_labels": [],
    "stamp_lag_s": [],
    # a stop on /opennav/stop once the chair moves, then "go on", "chair"
    "stop_sent": False,
    "answered_yes": 0,
    "stopped_state": None,
    "go_sent": False,
}


def take(r, n=50):
    """The samples with data (a writer gone is an invalid sample)."""
    return [s for s in r.take(N=n) if not type(s).__name__ == "InvalidSample"]


def lag(h):
    """Wall-clock now minus the message's stamp, seconds."""
    return time.time() - (h.stamp.sec + h.stamp.nanosec * 1e-9)


end = time.time() + limit
last_prompt = 0.0
while time.time() < end:
    heard += [s.data for s in take(said, 50)]
    states += [json.loads(s.data) for s in take(state, 50)]
    for side, r in scans.items():
        for s in take(r, 50):
            out["scans"][side] += 1
            if out["scan"] is None:
                finite = [x for x in s.ranges if math.isfinite(x)]
                out["scan"] = {
                    "frame_id": s.header.frame_id,
                    "n": len(s.ranges),
                    "finite": len(finite),
                    "inf": sum(1 for x in s.ranges if x == math.inf),
                    "nan": sum(1 for x in s.ranges if math.isnan(x)),
                    "angle_min": s.angle_min,
                    "angle_max": s.angle_max,
                    "angle_increment": s.angle_increment,
                    "range_max": s.range_max,
                    "min_finite": min(finite) if finite else None,
                }
                out["stamp_lag_s"].append(lag(s.header))
    for o in take(odom, 50):
        out["odom"] += 1
        p = o.pose.pose
        out["odom_last"] = {
            "frame_id": o.header.frame_id,
            "child_frame_id": o.child_frame_id,
            "x": p.position.x,
            "y": p.position.y,
            "qz": p.orientation.z,
            "qw": p.orientation.w,
            "cov_xx": o.pose.covariance[0],
            "cov_zz": o.pose.covariance[14],
            "v": o.twist.twist.linear.x,
            "lag_s": lag(o.header),
        }
    for m in take(tf, 50):
        for t in m.transforms:
            pair = [t.header.frame_id, t.child_frame_id]
            if pair not in out["tf"]:
                out["tf"].append(pair)
    for m in take(tf_static, 5):
        out["tf_static"] = [
            {"parent": t.header.frame_id, "child": t.child_frame_id,
             "xyz": [t.transform.translation.x, t.transform.translation.y, t.transform.translation.z]}
            for t in m.transforms
        ]
    for m in take(objects, 50):
        out["objects"] += 1
        for d in m.detections:
            for r in d.results:
                if r.hypothesis.class_id not in out["object_labels"]:
                    out["object_labels"].append(r.hypothesis.class_id)
            out["object_frame"] = d.header.frame_id
            out["object_size"] = [d.bbox.size.x, d.bbox.size.y, d.bbox.size.z]
    for m in take(tracks, 50):
        for d in m.detections:
            label = [d.results[0].hypothesis.class_id if d.results else None, d.id, d.header.frame_id]
            if label not in out["track_labels"]:
                out["track_labels"].append(label)
    going = heard or any(s.get("goal") == "chair" for s in states)
    if not going and time.time() - last_prompt > 0.5:
        prompt.write(String_(data="chair"))
        last_prompt = time.time()
    moving = any(s.get("moving") for s in states[-5:])
    if "Going to the chair." in heard and moving and not out["stop_sent"]:
        stop.write(String_(data=""))
        out["stop_sent"] = True
        stop_at = len(states)
    if out["stop_sent"] and out["stopped_state"] is None:
        after = [s for s in states[stop_at:] if not s.get("moving")]
        if after:
            out["stopped_state"] = after[0]
    if out["stopped_state"] is not None and not out["go_sent"]:
        # the stop ended the trip: go on, and the word again
        prompt.write(String_(data="go on"))
        time.sleep(0.3)
        prompt.write(String_(data="chair"))
        out["go_sent"] = True
    # asked whether it is clear behind (a turn on the spot with the rear
    # unseen): the carer, who can see that it is, answers each question
    asked = sum("Is it clear behind?" in h for h in heard)
    if asked > out["answered_yes"]:
        prompt.write(String_(data="yes"))
        out["answered_yes"] = asked
    if "Arrived at the chair." in heard:
        # and the daemon ends when told to
        prompt.write(String_(data="quit"))
        break
    time.sleep(0.05)
out.update({"heard": heard, "states": states[-3:], "n_states": len(states)})
print(json.dumps(out))
