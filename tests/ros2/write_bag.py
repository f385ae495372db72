"""Writes a ROS 2 bag (rosbag2, MCAP storage, CDR) from the simulator's renders with the
independent `rosbags` package: the frames `harvest rec export --png` wrote (frames.csv, 8-bit
RGB and 16-bit depth PNGs) as sensor_msgs/Image (colour as bgr8, depth as 32FC1 in metres, so
the import converts both), with their sensor_msgs/CameraInfo, stamped with each frame's
capture time; plus a topic the map does not name.

usage: write_bag.py FRAMES_DIR META.json OUT_BAG
META.json: {"rgb_intrinsics": {...}, "depth_intrinsics": {...}} as `harvest rec cat` prints them.
"""
import csv
import json
import sys
from pathlib import Path

import numpy as np
from PIL import Image as PilImage
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

frames_dir, meta_path, out = Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3])
meta = json.loads(meta_path.read_text())
store = get_typestore(Stores.ROS2_JAZZY)
Image = store.types["sensor_msgs/msg/Image"]
CameraInfo = store.types["sensor_msgs/msg/CameraInfo"]
RegionOfInterest = store.types["sensor_msgs/msg/RegionOfInterest"]
Header = store.types["std_msgs/msg/Header"]
Time = store.types["builtin_interfaces/msg/Time"]
String = store.types["std_msgs/msg/String"]


def header(stamp_ns, frame_id):
    return Header(stamp=Time(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9), frame_id=frame_id)


def camera_info(intrinsics, hdr):
    fx, fy, cx, cy = (intrinsics[k] for k in ("fx_px", "fy_px", "cx_px", "cy_px"))
    return CameraInfo(
        header=hdr,
        height=intrinsics["height_px"],
        width=intrinsics["width_px"],
        distortion_model="plumb_bob",
        d=np.array(intrinsics["distortion"], dtype=np.float64),
        k=np.array([fx, 0, cx, 0, fy, cy, 0, 0, 1], dtype=np.float64),
        r=np.array([1, 0, 0, 0, 1, 0, 0, 0, 1], dtype=np.float64),
        p=np.array([fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0], dtype=np.float64),
        binning_x=0,
        binning_y=0,
        roi=RegionOfInterest(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )


rows = list(csv.reader((frames_dir / "frames.csv").open()))
rows = [r for r in rows if r and r[0] != "topic"]
written = 0
with Writer(out, version=9, storage_plugin=StoragePlugin.MCAP) as bag:
    color = bag.add_connection("/cam/color/image_raw", Image.__msgtype__, typestore=store)
    color_info = bag.add_connection("/cam/color/camera_info", CameraInfo.__msgtype__, typestore=store)
    depth = bag.add_connection("/cam/depth/image_rect", Image.__msgtype__, typestore=store)
    depth_info = bag.add_connection("/cam/depth/camera_info", CameraInfo.__msgtype__, typestore=store)
    chatter = bag.add_connection("/chatter", String.__msgtype__, typestore=store)
    for _topic, _number, _seq, capture_ns, _log, rgb_name, depth_name in rows:
        stamp = int(capture_ns)
        rgb = np.asarray(PilImage.open(frames_dir / rgb_name).convert("RGB"), dtype=np.uint8)
        bgr = np.ascontiguousarray(rgb[:, :, ::-1])
        depth_mm = np.asarray(PilImage.open(frames_dir / depth_name), dtype=np.uint16)
        depth_m = (depth_mm.astype(np.float32) / np.float32(1000.0)).astype("<f4")
        h, w = rgb.shape[:2]
        dh, dw = depth_mm.shape
        color_header = header(stamp, "camera_color_optical_frame")
        # Depth a little later than colour, as two sensors of one camera stamp them.
        depth_header = header(stamp + 3_000_000, "camera_depth_optical_frame")
        msgs = [
            (color_info, camera_info(meta["rgb_intrinsics"], color_header)),
            (depth_info, camera_info(meta["depth_intrinsics"], depth_header)),
            (color, Image(header=color_header, height=h, width=w, encoding="bgr8",
                          is_bigendian=0, step=w * 3, data=bgr.reshape(-1))),
            (depth, Image(header=depth_header, height=dh, width=dw, encoding="32FC1",
                          is_bigendian=0, step=dw * 4, data=depth_m.view(np.uint8).reshape(-1))),
            (chatter, String(data="not mapped")),
        ]
        for connection, msg in msgs:
            bag.write(connection, stamp, store.serialize_cdr(msg, connection.msgtype))
            written += 1
print(json.dumps({"frames": len(rows), "messages": written}))
