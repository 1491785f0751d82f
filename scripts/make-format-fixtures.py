#!/usr/bin/env python3
"""Writes one known event list in every recording format evcal reads, with the tools
other people use to write them (not evcal's own writers):

- AEDAT4 by dv-processing (iniVation's library), one file per packet compression, with
  frame, IMU and trigger streams beside the events;
- ROS1 bags by rosbags, dvs_msgs/EventArray on /dvs/events (the message type registered
  from its .msg definition), a sensor_msgs/Imu topic and a second event topic, one bag per
  chunk compression (none, bz2, lz4);
- HDF5 by h5py: E-Calib's events_data, the events/{x,y,t,p} group (DSEC's, with t in µs
  from t_offset, Blosc-zstd compressed by hdf5plugin; and with t in ns, absolute, gzip), and
  e2calib's root x, y, p, t (t in ns, LZF-compressed, as e2calib's H5Writer writes it);
- the plain text `t x y p` list itself (events.txt), the reference the tests compare with.

evcal's tests (host-tools/tests/cli/formats.rs) read every file and require the same events as
events.txt. The committed fixtures in host-tools/tests/fixtures/formats/ were made by this
script with the writer versions scripts/setup.sh pins (it reproduces them byte for byte);
scripts/test.sh runs it again into target/ and reads what it wrote.

Usage: make-format-fixtures.py OUT_DIR [EVENTS]
(EVENTS, default 2000: larger lists for the read-throughput benchmark, benches/formats.rs)
"""

import sys
from pathlib import Path

import numpy as np

N = 2000
WIDTH, HEIGHT = 346, 260
T0_US = 1_600_000_000_123_456  # an absolute (epoch) time, as cameras stamp events
SEED = 5


def event_list():
    rng = np.random.default_rng(SEED)
    # Steps of 0..199 µs, some zero (equal timestamps happen in real streams).
    t = T0_US + np.cumsum(rng.integers(0, 200, N)).astype(np.int64)
    x = rng.integers(0, WIDTH, N).astype(np.uint16)
    y = rng.integers(0, HEIGHT, N).astype(np.uint16)
    p = rng.integers(0, 2, N).astype(np.uint8)
    # the corners too
    x[0], y[0], x[-1], y[-1] = 0, 0, WIDTH - 1, HEIGHT - 1
    return t, x, y, p


def write_text(out, t, x, y, p):
    with open(out / "events.txt", "w") as f:
        f.write(f"{WIDTH} {HEIGHT}\n")
        for ti, xi, yi, pi in zip(t.tolist(), x.tolist(), y.tolist(), p.tolist()):
            f.write(f"{ti // 1_000_000}.{ti % 1_000_000:06d} {xi} {yi} {pi}\n")


def write_aedat4(out, t, x, y, p):
    import dv_processing as dv

    # packets of a few thousand events, as DV writes them (8 for the small fixtures)
    batches = np.array_split(np.arange(N), max(8, N // 2500))
    for name, comp in [
        ("none", dv.CompressionType.NONE),
        ("lz4", dv.CompressionType.LZ4),
        ("lz4_high", dv.CompressionType.LZ4_HIGH),
        ("zstd", dv.CompressionType.ZSTD),
        ("zstd_high", dv.CompressionType.ZSTD_HIGH),
    ]:
        cfg = dv.io.MonoCameraWriter.Config("DAVIS346_fixture", comp)
        cfg.addEventStream((WIDTH, HEIGHT))
        cfg.addImuStream()
        cfg.addTriggerStream()
        # Frames only where compressed: a stored 346x260 frame would be 90 kB of fixture.
        with_frames = name != "none"
        if with_frames:
            cfg.addFrameStream((WIDTH, HEIGHT))
        path = out / f"dv_{name}.aedat4"
        path.unlink(missing_ok=True)
        w = dv.io.MonoCameraWriter(str(path), cfg)
        for k, idx in enumerate(batches):
            store = dv.EventStore()
            for i in idx.tolist():
                store.push_back(int(t[i]), int(x[i]), int(y[i]), bool(p[i]))
            w.writeEvents(store)
            ts = int(t[idx[-1]])
            w.writeImu(dv.IMU(ts, 25.0, 0.1, 0.2, 9.8, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
            w.writeTrigger(dv.Trigger(ts, dv.TriggerType.EXTERNAL_SIGNAL_RISING_EDGE))
            if with_frames and k % 4 == 0:
                w.writeFrame(dv.Frame(ts, np.full((HEIGHT, WIDTH), k % 256, dtype=np.uint8)))
        del w  # closing writes the data table


EVENT_MSG = """std_msgs/Header header
uint32 height
uint32 width
Event[] events
"""
EVENT_ITEM_MSG = """uint16 x
uint16 y
time ts
bool polarity
"""


def write_bags(out, t, x, y, p):
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    types = {}
    types.update(get_types_from_msg(EVENT_MSG, "dvs_msgs/msg/EventArray"))
    types.update(get_types_from_msg(EVENT_ITEM_MSG, "dvs_msgs/msg/Event"))
    store.register(types)
    EventArray = store.types["dvs_msgs/msg/EventArray"]
    Event = store.types["dvs_msgs/msg/Event"]
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    Imu = store.types["sensor_msgs/msg/Imu"]
    Quaternion = store.types["geometry_msgs/msg/Quaternion"]
    Vector3 = store.types["geometry_msgs/msg/Vector3"]

    def stamp(us):
        return Time(sec=int(us // 1_000_000), nanosec=int(us % 1_000_000) * 1000)

    def array(seq, idx):
        evs = [Event(x=int(x[i]), y=int(y[i]), ts=stamp(int(t[i])), polarity=bool(p[i])) for i in idx]
        hdr = Header(seq=seq, stamp=stamp(int(t[idx[0]])), frame_id="dvs")
        return EventArray(header=hdr, height=HEIGHT, width=WIDTH, events=evs)

    batches = [b.tolist() for b in np.array_split(np.arange(N), max(10, N // 5000))]
    for name, comp in [("none", None), ("bz2", Writer.CompressionFormat.BZ2), ("lz4", Writer.CompressionFormat.LZ4)]:
        path = out / f"ros_{name}.bag"
        path.unlink(missing_ok=True)
        w = Writer(path)
        if comp is not None:
            w.set_compression(comp)
        w.chunk_threshold = 8 * 1024  # several chunks, as long recordings have
        w.open()
        c_ev = w.add_connection("/dvs/events", "dvs_msgs/msg/EventArray", typestore=store)
        c_imu = w.add_connection("/dvs/imu", "sensor_msgs/msg/Imu", typestore=store)
        c_right = w.add_connection("/right/events", "dvs_msgs/msg/EventArray", typestore=store)
        for seq, idx in enumerate(batches):
            ns = int(t[idx[-1]]) * 1000
            w.write(c_ev, ns, store.serialize_ros1(array(seq, idx), "dvs_msgs/msg/EventArray"))
            imu = Imu(
                header=Header(seq=seq, stamp=stamp(int(t[idx[-1]])), frame_id="imu"),
                orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
                orientation_covariance=np.zeros(9),
                angular_velocity=Vector3(x=0.0, y=0.0, z=0.0),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=Vector3(x=0.0, y=0.0, z=9.8),
                linear_acceleration_covariance=np.zeros(9),
            )
            w.write(c_imu, ns, store.serialize_ros1(imu, "sensor_msgs/msg/Imu"))
            if seq == 0:
                # the second event topic: the first 100 events, for --topic
                w.write(c_right, ns, store.serialize_ros1(array(0, list(range(100))), "dvs_msgs/msg/EventArray"))
        w.close()


def write_h5(out, t, x, y, p):
    import h5py

    # E-Calib: events_data, N x 4 float64 [x, y, p, t_seconds]
    with h5py.File(out / "ecalib.h5", "w") as f:
        f["events_data"] = np.stack([x, y, p, t / 1e6], axis=1).astype(np.float64)

    # DSEC: events/{p,t,x,y}, t in µs (uint32) from t_offset; ms_to_idx; Blosc-zstd chunks
    # (hdf5plugin), as DSEC's files are compressed.
    import hdf5plugin

    blosc = hdf5plugin.Blosc(cname="zstd", clevel=5, shuffle=hdf5plugin.Blosc.SHUFFLE)
    t_offset = int(t[0]) - 1234
    with h5py.File(out / "dsec.h5", "w") as f:
        g = f.create_group("events")
        g.create_dataset("p", data=p, chunks=(max(512, N // 32),), **blosc)
        g.create_dataset("t", data=(t - t_offset).astype(np.uint32), chunks=(max(512, N // 32),), **blosc)
        g.create_dataset("x", data=x, chunks=(max(512, N // 32),), **blosc)
        g.create_dataset("y", data=y, chunks=(max(512, N // 32),), **blosc)
        f.create_dataset("t_offset", data=np.int64(t_offset))
        ms = np.searchsorted(t - t_offset, np.arange(0, (t[-1] - t_offset) // 1000 + 1) * 1000)
        f.create_dataset("ms_to_idx", data=ms.astype(np.uint64))

    # events/{x,y,t,p} with t in ns (absolute, int64), polarity as -1/1 int8, sensor size
    # as attributes of the group, gzip (HDF5's own deflate).
    with h5py.File(out / "events_ns.h5", "w") as f:
        g = f.create_group("events")
        g.attrs["width"] = WIDTH
        g.attrs["height"] = HEIGHT
        for name, v in [("x", x), ("y", y), ("t", t * 1000), ("p", p.astype(np.int8) * 2 - 1)]:
            g.create_dataset(name, data=v, compression="gzip", chunks=(max(700, N // 32),))

    # hdf5plugin's Zstandard filter (32015), which evcal does not build in: the error must
    # name it and the way to load it (HDF5_PLUGIN_PATH).
    with h5py.File(out / "zstd_filter.h5", "w") as f:
        g = f.create_group("events")
        for name, v in [("x", x[:10]), ("y", y[:10]), ("t", t[:10]), ("p", p[:10])]:
            g.create_dataset(name, data=v, **hdf5plugin.Zstd())

    # e2calib's H5Writer: root x, y (u2), p (u1), t (i8, ns), LZF, 2**16-row chunks, resizable.
    with h5py.File(out / "e2calib.h5", "w") as f:
        shape, maxshape = (2**16,), (None,)
        for name, dtype in [("x", "u2"), ("y", "u2"), ("p", "u1"), ("t", "i8")]:
            f.create_dataset(name, shape=shape, dtype=dtype, chunks=shape, maxshape=maxshape, compression="lzf")
        for name, v in [("x", x), ("y", y), ("p", p), ("t", t * 1000)]:
            f[name].resize(N, axis=0)
            f[name][:] = v


def main():
    global N
    if len(sys.argv) not in (2, 3):
        sys.exit(__doc__)
    if len(sys.argv) == 3:
        N = int(sys.argv[2])
    out = Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    t, x, y, p = event_list()
    write_text(out, t, x, y, p)
    write_aedat4(out, t, x, y, p)
    write_bags(out, t, x, y, p)
    write_h5(out, t, x, y, p)
    print(f"{N} events written in every format to {out}")


if __name__ == "__main__":
    main()
