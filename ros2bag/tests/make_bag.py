#!/usr/bin/env python3
"""Writes rosbag2 (MCAP, CDR) test bags with the `rosbags` package, an independent writer.

The Rust tests (ros2bag/tests/import.rs) call this script; install its one dependency with
`bash scripts/setup.sh` (pip install rosbags==0.11.9).

Two sources:
  --csv REC.csv --robot robot.toml   a formats.md recording turned into a bag: encoder
                                     counts -> JointState radians (counts x 2 pi / cpr),
                                     the start-frame poses moved into a `map` frame by a
                                     fixed offset, t -> Unix-time header stamps
  --synthetic SECONDS --robot R      a differential drive on a smooth path, joints and poses
                                     at different instants (to exercise interpolation),
                                     and cmd_vel

Pose topics (--pose): posestamped (/mocap/pose, frame map), odometry (/mocap/odom, map ->
base_link), tf (/tf_static map -> mocap, /tf mocap -> base_link), none.
Prints a JSON line with what it wrote (chunk offsets, the corrupted chunk's offset).
"""

import argparse
import csv
import json
import math
import sys
import tomllib
from pathlib import Path

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
from rosbags.typesys import Stores, get_typestore

STORE = get_typestore(Stores.ROS2_HUMBLE)
T = STORE.types
Time = T['builtin_interfaces/msg/Time']
Header = T['std_msgs/msg/Header']
JointState = T['sensor_msgs/msg/JointState']
Point = T['geometry_msgs/msg/Point']
Vector3 = T['geometry_msgs/msg/Vector3']
Quaternion = T['geometry_msgs/msg/Quaternion']
Pose = T['geometry_msgs/msg/Pose']
PoseStamped = T['geometry_msgs/msg/PoseStamped']
PoseWithCovariance = T['geometry_msgs/msg/PoseWithCovariance']
Twist = T['geometry_msgs/msg/Twist']
TwistStamped = T['geometry_msgs/msg/TwistStamped']
TwistWithCovariance = T['geometry_msgs/msg/TwistWithCovariance']
Odometry = T['nav_msgs/msg/Odometry']
Transform = T['geometry_msgs/msg/Transform']
TransformStamped = T['geometry_msgs/msg/TransformStamped']
TFMessage = T['tf2_msgs/msg/TFMessage']

import numpy as np  # noqa: E402  (rosbags depends on numpy)

# 23 December 2020 00:29 UTC, the session of the real squares.
EPOCH_NS = 1608683340 * 10**9
# Where the start of the recording is in the map frame (x, y, yaw).
MAP_OFFSET = (3.25, -1.75, 2.5)
# The static map -> mocap transform of the tf variant.
STATIC = (-0.8, 0.4, -1.1)
# Receive time after the header stamp.
RECEIVE_DELAY_NS = 3_000_000


def compose(a, b):
    """Planar pose a then b (b expressed in a's frame)."""
    ax, ay, at = a
    bx, by, bt = b
    c, s = math.cos(at), math.sin(at)
    return (ax + c * bx - s * by, ay + s * bx + c * by, at + bt)


def inverse(a):
    ax, ay, at = a
    c, s = math.cos(at), math.sin(at)
    return (-(c * ax + s * ay), s * ax - c * ay, -at)


def stamp(ns):
    return Time(sec=ns // 10**9, nanosec=ns % 10**9)


def quat(yaw):
    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def header(ns, frame):
    return Header(stamp=stamp(ns), frame_id=frame)


def pose_msgs(kind, ns, pose):
    """(topic, msgtype, message) for one pose sample of `kind` (pose in the map frame)."""
    x, y, yaw = pose
    p = Pose(position=Point(x=x, y=y, z=0.0), orientation=quat(yaw))
    if kind == 'posestamped':
        return [('/mocap/pose', PoseStamped.__msgtype__, PoseStamped(header=header(ns, 'map'), pose=p))]
    if kind == 'odometry':
        cov = np.zeros(36, dtype=np.float64)
        tw = TwistWithCovariance(
            twist=Twist(linear=Vector3(x=0.0, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0)),
            covariance=cov,
        )
        msg = Odometry(
            header=header(ns, 'map'),
            child_frame_id='base_link',
            pose=PoseWithCovariance(pose=p, covariance=cov),
            twist=tw,
        )
        return [('/mocap/odom', Odometry.__msgtype__, msg)]
    if kind == 'tf':
        # map -> mocap is static; mocap -> base_link carries the motion.
        rel = compose(inverse(STATIC), pose)
        tf = TransformStamped(
            header=header(ns, 'mocap'),
            child_frame_id='base_link',
            transform=Transform(translation=Vector3(x=rel[0], y=rel[1], z=0.0), rotation=quat(rel[2])),
        )
        return [('/tf', TFMessage.__msgtype__, TFMessage(transforms=[tf]))]
    return []


def static_tf(ns):
    tf = TransformStamped(
        header=header(ns, 'map'),
        child_frame_id='mocap',
        transform=Transform(
            translation=Vector3(x=STATIC[0], y=STATIC[1], z=0.0), rotation=quat(STATIC[2])
        ),
    )
    return TFMessage(transforms=[tf])


def joint_msg(ns, names, positions):
    n = len(names)
    return JointState(
        header=header(ns, ''),
        name=names,
        position=np.array(positions, dtype=np.float64),
        velocity=np.zeros(n, dtype=np.float64),
        effort=np.zeros(n, dtype=np.float64),
    )


def from_csv(path, robot):
    """(t_ns, {wheel: counts}, pose or None) rows of a formats.md recording."""
    wheels = [w['name'] for w in robot['wheels']]
    rows = []
    with open(path, newline='') as f:
        for r in csv.DictReader(f):
            t_ns = EPOCH_NS + round(float(r['t']) * 1e9)
            enc = {w: int(r['enc_' + w]) for w in wheels}
            pose = None
            if r['x'] != '':
                pose = compose(MAP_OFFSET, (float(r['x']), float(r['y']), float(r['theta'])))
            rows.append((t_ns, enc, pose))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument('--robot', required=True)
    ap.add_argument('--csv')
    ap.add_argument('--synthetic', type=float, help='seconds of synthetic driving')
    ap.add_argument('--truth', help='synthetic: write the true start-frame path at the joint instants here')
    ap.add_argument('--out', required=True)
    ap.add_argument('--pose', default='posestamped', choices=['posestamped', 'odometry', 'tf', 'none'])
    ap.add_argument('--joint-suffix', default='_wheel_joint')
    ap.add_argument('--pose-noise', type=float, default=0.0,
                    help='synthetic: SLAM-like white noise on each pose, m (and the same in rad x 0.5)')
    ap.add_argument('--jump', action='append', default=[],
                    help='synthetic: T:DX:DY:DYAW, from T s on the poses are corrected by a loop closure '
                         'that moves the robot by (DX, DY) and turns it by DYAW about itself')
    ap.add_argument('--compress', action='store_true', help='zstd chunks (as ros2 bag record)')
    ap.add_argument('--corrupt-chunk', type=int, help='overwrite the zstd frame of this chunk (0-based)')
    ap.add_argument('--poison', action='append', default=[],
                    help='synthetic: KIND@T, one corrupted-but-decodable message at T s: nan-joint, '
                         'inf-joint (a joint position), zero-quat (a pose quaternion of zeros), '
                         'far-stamp (a joint stamp 2^31-1 s)')
    a = ap.parse_args()

    with open(a.robot, 'rb') as f:
        robot = tomllib.load(f)
    wheels = [w['name'] for w in robot['wheels']]
    cpr = float(robot['drive']['encoder_counts_per_rev'])
    names = [w + a.joint_suffix for w in wheels] + ['caster_swivel_joint']

    out = Path(a.out)
    writer = Writer(out, version=9, storage_plugin=StoragePlugin.MCAP)
    if a.compress or a.corrupt_chunk is not None:
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    # (receive ns, topic, msgtype, message)
    msgs = []
    if a.csv:
        for t_ns, enc, pose in from_csv(a.csv, robot):
            pos = [enc[w] * 2 * math.pi / cpr for w in wheels] + [0.25]
            msgs.append((t_ns + RECEIVE_DELAY_NS, '/joint_states', JointState.__msgtype__, joint_msg(t_ns, names, pos)))
            if pose is not None:
                for topic, ty, m in pose_msgs(a.pose, t_ns, pose):
                    msgs.append((t_ns + RECEIVE_DELAY_NS, topic, ty, m))
    else:
        # A differential drive at v = 0.3 m/s turning with omega = 0.5 sin(0.1 t),
        # integrated in exact arcs of 1 ms; joints at 100 Hz, poses at 33.3 Hz at other
        # instants (7 ms later), cmd_vel (TwistStamped) at 20 Hz. --truth gets the pose
        # (start frame), counts and held wheel commands at every joint instant.
        r = robot['wheels'][0]['radius_m']
        b = robot['wheels'][0]['l_m']
        dt = 0.001
        n = int(round(a.synthetic / dt))
        x = y = th = 0.0
        phi_l = phi_r = 0.0
        cmd = None
        truth = []
        import random
        rng = random.Random(7)
        # [t, dx, dy, dyaw, x at t, y at t]: the centre is filled in when t is reached
        jumps = [[float(v) for v in j.split(':')] + [None, None] for j in a.jump]
        poison = [(p.split('@')[0], float(p.split('@')[1])) for p in a.poison]
        pending = sorted(range(len(jumps)), key=lambda i: jumps[i][0])
        for k in range(n + 1):
            t_ns = EPOCH_NS + k * 1_000_000
            t = k * dt
            v, w = 0.3, 0.5 * math.sin(0.1 * t)
            while pending and t >= jumps[pending[0]][0]:
                jumps[pending[0]][4:6] = [x, y]
                pending.pop(0)
            if k % 50 == 0:
                tw = TwistStamped(
                    header=header(t_ns, 'base_link'),
                    twist=Twist(linear=Vector3(x=v, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=w)),
                )
                msgs.append((t_ns + RECEIVE_DELAY_NS, '/cmd_vel', TwistStamped.__msgtype__, tw))
                cmd = ((v - w * b) / r, (v + w * b) / r)
            if k % 10 == 0:
                enc = [round(phi_l * cpr / (2 * math.pi)), round(phi_r * cpr / (2 * math.pi))]
                pos = [c * 2 * math.pi / cpr for c in enc] + [0.25]
                stamp_ns = t_ns
                for kind, tp in poison:
                    if abs(t - tp) < 0.5e-3:
                        if kind == 'nan-joint':
                            pos[0] = float('nan')
                        elif kind == 'inf-joint':
                            pos[1] = float('inf')
                        elif kind == 'far-stamp':
                            stamp_ns = (2**31 - 1) * 1_000_000_000
                msgs.append((t_ns + RECEIVE_DELAY_NS, '/joint_states', JointState.__msgtype__, joint_msg(stamp_ns, names, pos)))
                truth.append((t, cmd[0], cmd[1], enc[0], enc[1], x, y, th))
            if k % 30 == 7:
                px, py, pth = x, y, th
                for tj, jx, jy, jth, cx, cy in jumps:
                    if t >= tj:
                        # rotate about the robot's position at the jump, then shift
                        c, s = math.cos(jth), math.sin(jth)
                        rx, ry = px - cx, py - cy
                        px, py, pth = cx + c * rx - s * ry + jx, cy + s * rx + c * ry + jy, pth + jth
                if a.pose_noise > 0:
                    px += rng.gauss(0, a.pose_noise)
                    py += rng.gauss(0, a.pose_noise)
                    pth += rng.gauss(0, 0.5 * a.pose_noise)
                for topic, ty, m in pose_msgs(a.pose, t_ns, compose(MAP_OFFSET, (px, py, pth))):
                    if any(kind == 'zero-quat' and abs(t - tp) < 0.5e-3 for kind, tp in poison):
                        m.pose.orientation = Quaternion(x=0.0, y=0.0, z=0.0, w=0.0)
                    msgs.append((t_ns + RECEIVE_DELAY_NS, topic, ty, m))
            if abs(w) > 1e-12:
                x += v / w * (math.sin(th + w * dt) - math.sin(th))
                y += -v / w * (math.cos(th + w * dt) - math.cos(th))
            else:
                x += v * dt * math.cos(th)
                y += v * dt * math.sin(th)
            th += w * dt
            phi_l += (v - w * b) / r * dt
            phi_r += (v + w * b) / r * dt
        if a.truth:
            with open(a.truth, 'w', newline='') as f:
                wr = csv.writer(f)
                wr.writerow(['t', 'cmd_left', 'cmd_right', 'enc_left', 'enc_right', 'x', 'y', 'theta'])
                for row in truth:
                    wr.writerow([repr(v) for v in row])
    msgs.sort(key=lambda m: m[0])

    with writer:
        conns = {}
        if a.pose == 'tf':
            c = writer.add_connection('/tf_static', TFMessage.__msgtype__, typestore=STORE)
            writer.write(c, msgs[0][0], STORE.serialize_cdr(static_tf(msgs[0][0]), TFMessage.__msgtype__))
        # Which chunk each joint message lands in (rosbags closes a chunk past 1 MiB;
        # its writer's list of closed chunks says which one is open).
        joint_chunks = []
        for recv, topic, ty, m in msgs:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, ty, typestore=STORE)
            if topic == '/joint_states':
                joint_chunks.append(len(writer.storage.chunks))
            writer.write(conns[topic], recv, STORE.serialize_cdr(m, ty))

    mcap = out / f'{out.name}.mcap'
    data = bytearray(mcap.read_bytes())
    magic = b'\x28\xb5\x2f\xfd'
    frames = []
    i = data.find(magic)
    while i >= 0:
        if data[i - 12 : i - 8] == b'zstd':  # a chunk's records, not bytes inside them
            frames.append(i)
        i = data.find(magic, i + 1)
    # A chunk record: opcode 1, length 8, start/end time 16, uncompressed size 8, crc 4,
    # compression string (4 + 4 bytes 'zstd'), compressed size 8, then the records.
    chunk_offsets = [f - (1 + 8 + 16 + 8 + 4 + 8 + 8) for f in frames]
    report = {'messages': len(msgs), 'chunk_offsets': chunk_offsets, 'mcap': str(mcap)}
    if a.corrupt_chunk is not None:
        if a.corrupt_chunk >= len(frames):
            sys.exit(f'only {len(frames)} zstd chunks, cannot corrupt chunk {a.corrupt_chunk}')
        f = frames[a.corrupt_chunk]
        data[f : f + 4] = b'\0\0\0\0'
        mcap.write_bytes(bytes(data))
        report['corrupted_offset'] = chunk_offsets[a.corrupt_chunk]
        report['joint_messages_before'] = sum(1 for c in joint_chunks if c < a.corrupt_chunk)
    print(json.dumps(report))


if __name__ == '__main__':
    main()
