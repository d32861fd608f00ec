"""Inputs by URL against a real S3 protocol server (moto's, on 127.0.0.1): byte-range reads, the cache,
retries and timeouts, credentials never shown, batch over prefixes and globs, Dask workers that open URLs."""
from __future__ import annotations

import contextlib
import gc
import json
import os
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator

import numpy as np
import pytest
from _util import ROOT, run

moto_server = pytest.importorskip("moto.server", reason="pip install '.[test]' (moto[server], s3fs)")
boto3 = pytest.importorskip("boto3")

SAMPLES = ROOT / "sample_data"
BUCKET = "fleet"
TOPICS = ("--topic-a", "/cam0/pose", "--topic-b", "/cam1/pose")
SECRET = "s3cr3t-Do-Not-Print-9f2e"       # the secret key: must appear in no output
KEY_ID = "AKIAHANDEYETEST0001"

# A socket a test leaves open is an error here, in the test that left it: collected after each test, not later
# in whichever test of another file the worker runs when the collector passes (CI failed that way once).
pytestmark = pytest.mark.filterwarnings("error::ResourceWarning",
                                        "error::pytest.PytestUnraisableExceptionWarning")


@pytest.fixture(autouse=True)
def _collected():
    yield
    gc.collect()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope="module")
def s3():
    """A moto S3 server with the sample logs (and a cut one) in the bucket ``fleet``; the environment
    points boto at it with the test's credentials."""
    port = _free_port()
    server = moto_server.ThreadedMotoServer(ip_address="127.0.0.1", port=port)
    server.start()
    endpoint = f"http://127.0.0.1:{port}"
    env = {"AWS_ENDPOINT_URL": endpoint, "AWS_ACCESS_KEY_ID": KEY_ID, "AWS_SECRET_ACCESS_KEY": SECRET,
           "AWS_DEFAULT_REGION": "us-east-1"}
    old = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    client = boto3.client("s3", endpoint_url=endpoint)
    client.create_bucket(Bucket=BUCKET)
    for name in ("rig.mcap", "rig_json.mcap", "rig_a.tum", "rig_b.tum"):
        client.upload_file(str(SAMPLES / name), BUCKET, f"logs/{name}")
    client.upload_file(str(SAMPLES / "rig.mcap"), BUCKET, "logs/day2/rig.mcap")
    client.upload_file(str(SAMPLES / "rig_ros1.bag"), BUCKET, "bags/rig_ros1.bag")
    for f in sorted((SAMPLES / "rig_ros2").iterdir()):
        client.upload_file(str(f), BUCKET, f"bags/rig_ros2/{f.name}")
    data = (SAMPLES / "rig.mcap").read_bytes()
    client.put_object(Bucket=BUCKET, Key="cut/rig_cut.mcap", Body=data[: len(data) * 6 // 10])
    yield endpoint
    server.stop()
    for k, v in old.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v


def _doc(out: str) -> dict:
    import yaml

    return yaml.safe_load(out)


def _same_result(a: dict, b: dict) -> None:
    assert a["matrix"] == b["matrix"] and a["pairs_used"] == b["pairs_used"] and a["frames"] == b["frames"]
    assert a["samples"] == b["samples"]


def test_calibrate_from_s3_equals_the_local_result_and_reports_bytes(s3, capsys):
    code, local, _ = run(capsys, "calibrate", SAMPLES / "rig.mcap", *TOPICS, "-q")
    code_r, remote, err = run(capsys, "calibrate", f"s3://{BUCKET}/logs/rig.mcap", *TOPICS, "-q")
    assert code == code_r == 0, err
    a, b = _doc(local), _doc(remote)
    _same_result(a, b)
    size = (SAMPLES / "rig.mcap").stat().st_size
    assert 0 < b["inputs"]["bytes_fetched"] <= size + 8192 and "bytes_fetched" not in a["inputs"]
    assert b["inputs"]["a"]["file"] == f"s3://{BUCKET}/logs/rig.mcap"


@pytest.mark.parametrize(("name", "topics"), [("rig_ros2", ("/cam0/transform", "/cam1/odom"))])
def test_logs_read_from_the_cache_say_so_and_equal_local(s3, capsys, name, topics):
    flags = ("--topic-a", topics[0], "--topic-b", topics[1], "-q")
    code, local, _ = run(capsys, "calibrate", SAMPLES / name, *flags)
    code_r, remote, err = run(capsys, "calibrate", f"s3://{BUCKET}/bags/{name}", *flags)
    assert code == code_r == 0, err
    _same_result(_doc(local), _doc(remote))
    assert any("downloaded it whole to a temporary cache" in w for w in _doc(remote)["warnings"])


def test_text_pair_and_inspect(s3, capsys):
    code, local, _ = run(capsys, "calibrate", SAMPLES / "rig_a.tum", SAMPLES / "rig_b.tum", "-q")
    code_r, remote, err = run(capsys, "calibrate", f"s3://{BUCKET}/logs/rig_a.tum", f"s3://{BUCKET}/logs/rig_b.tum",
                              "-q")
    assert code == code_r == 0, err
    _same_result(_doc(local), _doc(remote))
    code, out, err = run(capsys, "inspect", f"s3://{BUCKET}/logs/rig.mcap", "--format", "json")
    info = json.loads(out)
    assert code == 0 and info["path"] == f"s3://{BUCKET}/logs/rig.mcap"
    assert {t["topic"] for t in info["topics"]} >= {"/cam0/pose", "/cam1/pose"}
    _, local_out, _ = run(capsys, "inspect", SAMPLES / "rig.mcap", "--format", "json")
    local_info = json.loads(local_out)           # each topic's span from its message indexes, read by range
    assert info["topics"] == local_info["topics"] and info["tf_frames"] == local_info["tf_frames"]


def test_remote_and_local_mcap_streams_are_identical(s3):
    import numpy as np

    from handeye_cli.io import read_log_streams
    from handeye_cli.io.remote import session

    requests = [("/cam0/pose", None), ("/cam1/pose", None)]
    for name in ("rig.mcap", "rig_json.mcap"):      # the fast path, and the generic reader on a range file
        local = read_log_streams(SAMPLES / name, requests)
        with session((), 10.0, 2) as s:
            remote = read_log_streams(f"s3://{BUCKET}/logs/{name}", requests)
        assert s.bytes_fetched > 0 and not s.notes              # read by range: nothing downloaded
        for x, y in zip(local, remote, strict=True):
            assert np.array_equal(x.stamps_ns, y.stamps_ns) and np.array_equal(x.xyz, y.xyz)
            assert np.array_equal(x.quat_xyzw, y.quat_xyzw)


def test_only_the_wanted_chunks_are_fetched(tmp_path):
    """Poses in their own chunks, images beside: fetched ≤ 1.2 × (footer + summary + pose chunks with
    their message indexes), by the file's own chunk index (served from memory://). The first and last
    bytes read ahead with the object's size add at most _READAHEAD + _TAIL (20 KiB) to any read: the
    log is long enough (20 s) for its bound to dwarf them, as a fleet log's does."""
    import fsspec

    sys.path.insert(0, str(ROOT / "benchmarks"))
    from remote import lower_bound, write_image_log

    path = write_image_log(tmp_path / "img.mcap", seconds=20, image_bytes=40_000, own_chunks=True)
    with fsspec.open("memory://img/img.mcap", "wb") as f:
        f.write(path.read_bytes())
    from handeye_cli.io import read_log_streams
    from handeye_cli.io.remote import session

    with session((), 10.0, 2) as s:
        read_log_streams("memory://img/img.mcap", [("/cam0/pose", None), ("/cam1/pose", None)])
    bound = lower_bound(path)
    assert bound < 0.05 * path.stat().st_size
    assert bound <= s.bytes_fetched <= 1.2 * bound


def test_batch_over_a_prefix_and_a_glob(s3, capsys):
    code, out, err = run(capsys, "batch", f"s3://{BUCKET}/logs/", *TOPICS, "-q", "--jobs", "1")
    records = [json.loads(line) for line in out.splitlines()]
    assert [r["input"] for r in records] == [f"s3://{BUCKET}/logs/{n}" for n in
                                             ("day2/rig.mcap", "rig.mcap", "rig_json.mcap")]
    assert code == 0 and all(r["status"] == "ok" and r["inputs"]["bytes_fetched"] > 0 for r in records), err
    code, out, _ = run(capsys, "batch", f"s3://{BUCKET}/logs/rig*.mcap", f"s3://{BUCKET}/logs/missing.mcap",
                       f"s3://{BUCKET}/logs/rig_a.tum", *TOPICS, "-q", "--jobs", "1")
    records = [json.loads(line) for line in out.splitlines()]
    assert [r["status"] for r in records] == ["ok", "ok", "error", "error"] and code == 2
    assert records[0]["input"] == f"s3://{BUCKET}/logs/rig.mcap"
    assert records[2]["error"].startswith("no such object") and "\n" not in records[2]["error"]


def test_an_object_cut_short_is_salvaged_like_a_local_file(s3, capsys, tmp_path):
    data = (SAMPLES / "rig.mcap").read_bytes()
    (tmp_path / "rig_cut.mcap").write_bytes(data[: len(data) * 6 // 10])
    code, local, _ = run(capsys, "calibrate", tmp_path / "rig_cut.mcap", *TOPICS, "-q")
    code_r, remote, _ = run(capsys, "calibrate", f"s3://{BUCKET}/cut/rig_cut.mcap", *TOPICS, "-q")
    assert code == code_r
    a, b = _doc(local), _doc(remote)
    _same_result(a, b)
    assert any("recovered" in w for w in b["warnings"]) and any("cache" in w for w in b["warnings"])


@contextlib.contextmanager
def _silent_server() -> Iterator[int]:
    """A server on 127.0.0.1 that accepts connections and never answers: its port; its socket and the
    connections it holds are closed on exit."""
    held: list[socket.socket] = []
    with socket.socket() as srv:
        srv.bind(("127.0.0.1", 0))
        srv.listen(16)
        threading.Thread(target=lambda: [held.append(srv.accept()[0]) for _ in range(16)], daemon=True).start()
        try:
            yield srv.getsockname()[1]
        finally:
            for connection in held:
                connection.close()


def test_a_stalled_server_is_a_timeout_not_a_hang(s3, capsys):
    start = time.monotonic()
    with _silent_server() as port:
        code, out, err = run(capsys, "calibrate", f"s3://{BUCKET}/logs/rig.mcap", *TOPICS, "-q",
                             "--storage-option", f"endpoint_url=http://127.0.0.1:{port}",
                             "--remote-timeout", "0.5", "--remote-retries", "2")
    assert time.monotonic() - start < 8
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert "failed 2 times (no answer in time" in err


def test_wrong_credentials_are_one_clear_line_and_no_secret_is_shown(s3, capsys, tmp_path):
    import moto.settings

    iam = boto3.client("iam", endpoint_url=s3)
    iam.create_user(UserName="ci")
    policy = iam.create_policy(PolicyName="all", PolicyDocument=json.dumps(
        {"Version": "2012-10-17", "Statement": [{"Effect": "Allow", "Action": "*", "Resource": "*"}]}))
    iam.attach_user_policy(UserName="ci", PolicyArn=policy["Policy"]["Arn"])
    key = iam.create_access_key(UserName="ci")["AccessKey"]
    old = moto.settings.INITIAL_NO_AUTH_ACTION_COUNT
    moto.settings.INITIAL_NO_AUTH_ACTION_COUNT = 0          # from now on the server checks signatures
    try:
        code, out, err = run(capsys, "calibrate", f"s3://{BUCKET}/logs/rig.mcap", *TOPICS, "-q")
        assert code == 2 and out == "" and len(err.strip().splitlines()) == 1
        assert "access denied" in err and SECRET not in err and KEY_ID not in err
        good = key["SecretAccessKey"]
        texts = []
        for fmt in ("yaml", "json"):
            code, out, err = run(capsys, "calibrate", f"s3://{BUCKET}/logs/rig.mcap", *TOPICS, "--format", fmt,
                                 "--storage-option", f"key={key['AccessKeyId']}", "--storage-option",
                                 f"secret={good}", "--report", tmp_path / "r.html", "-o", tmp_path / f"r.{fmt}")
            assert code == 0, err
            texts += [out, err, (tmp_path / f"r.{fmt}").read_text(), (tmp_path / "r.html").read_text()]
        code, out, err = run(capsys, "batch", f"s3://{BUCKET}/logs/", *TOPICS, "--jobs", "1", "--storage-option",
                             f"key={key['AccessKeyId']}", "--storage-option", f"secret={good}",
                             "--output-dir", tmp_path / "res")
        texts += [out, err, *(p.read_text() for p in (tmp_path / "res").iterdir())]
        code, out, err = run(capsys, "calibrate", f"s3://{BUCKET}/logs/rig.mcap", *TOPICS,
                             "--storage-option", f"secret{good}")
        texts += [out, err]
        assert code == 2 and "bad storage option" in err
        for text in texts:
            assert good not in text and SECRET not in text
    finally:
        moto.settings.INITIAL_NO_AUTH_ACTION_COUNT = old


def test_a_local_run_does_not_import_fsspec():
    probe = ("import sys\nfrom handeye_cli.cli import main\ntry:\n"
             f"    main(['calibrate', {str(SAMPLES / 'rig.mcap')!r}, '--topic-a', '/cam0/pose',"
             " '--topic-b', '/cam1/pose', '-q'])\n"
             "except SystemExit as e:\n    assert e.code == 0, e.code\n"
             "sys.stderr.write(repr(('fsspec' in sys.modules, 's3fs' in sys.modules)))\n")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, cwd=ROOT,
                         env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert out.returncode == 0 and out.stderr.strip().endswith("(False, False)"), out.stderr[-300:]


def test_dask_workers_open_the_urls_themselves(s3, capsys, tmp_path):
    pytest.importorskip("distributed")
    port = _free_port()
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                               "--port", str(port), "--no-dashboard"], env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)]
    try:
        for _ in range(2):
            procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker",
                                           f"tcp://127.0.0.1:{port}", "--nthreads", "1", "--no-dashboard"],
                                          env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        args = ("batch", f"s3://{BUCKET}/logs/", *TOPICS, "-q")
        from distributed import Client

        with Client(f"tcp://127.0.0.1:{port}", timeout=30) as client:
            client.wait_for_workers(2, timeout=30)
        code, local, _ = run(capsys, *args, "--jobs", "1")
        code_d, remote, err = run(capsys, *args, "--scheduler", f"tcp://127.0.0.1:{port}")
        assert code == code_d == 0, err

        def strip(out: str) -> list[dict]:
            return [{k: v for k, v in json.loads(line).items() if k != "seconds"} for line in out.splitlines()]

        assert strip(local) == strip(remote) and len(strip(local)) == 3
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            p.wait(10)


def test_the_readme_nightly_job_reads_s3_directly(s3, capsys, tmp_path, monkeypatch):
    """The README's "CI and fleets" workflow: its install step has the remote extra, and its batch
    command runs against the local server (bucket and nominal swapped for the test's)."""
    import re
    import shlex

    import yaml

    section = (ROOT / "README.md").read_text(encoding="utf-8").split("## CI and fleets", 1)[1]
    workflow = yaml.safe_load(re.search(r"```yaml\n(.*?)```", section, re.S).group(1))
    steps = workflow["jobs"]["recalibrate"]["steps"]
    assert any("remote" in step.get("run", "") and "pip install" in step["run"] for step in steps)
    (step,) = [s for s in steps if s.get("run", "").startswith("handeye batch")]
    assert set(step["env"]) == {"AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY"}
    command, redirect = step["run"].strip().split(" > ")
    argv = shlex.split(command)
    assert argv[2].startswith("s3://")
    code, nominal, _ = run(capsys, "calibrate", SAMPLES / "rig.mcap", *TOPICS, "-q")
    (tmp_path / "nominal").mkdir()
    (tmp_path / "nominal" / "robot42.yaml").write_text(nominal)
    argv = [f"s3://{BUCKET}/logs/" if a == argv[2] else "nominal/robot42.yaml" if a.startswith("nominal/") else a
            for a in argv]
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, *argv[1:])
    assert code == 0, err
    records = [json.loads(line) for line in out.splitlines()]
    assert len(records) == 3 and all(r["status"] == "ok" and r["inputs"]["bytes_fetched"] > 0 for r in records)
    assert (tmp_path / "fleet.html").is_file() and redirect.strip() == "verdicts.jsonl"


def _image_bag(tmp_path, key: str):
    """A small image-heavy ROS 1 bag (20 s: its bound dwarfs the 20 KiB read ahead, see
    test_only_the_wanted_chunks_are_fetched) with every second of poses in a chunk of its own, uploaded
    as ``key``; (its path, its lower bound by its own index)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from remote import lower_bound_bag, write_image_bag

    path = write_image_bag(tmp_path / "img.bag", seconds=20, image_bytes=40_000, own_chunks=True)
    boto3.client("s3").upload_file(str(path), BUCKET, key)
    return path, lower_bound_bag(path)


def test_an_indexed_ros1_bag_is_read_by_range(s3, tmp_path):
    """The bag header, the index, then only the pose chunks: fetched ≤ 1.2 × that lower bound, a few
    per cent of the object, and the streams equal the local read (rosbags)."""
    import numpy as np

    from handeye_cli.io import read_log_streams
    from handeye_cli.io.remote import session

    path, bound = _image_bag(tmp_path, "bags/img.bag")
    requests = [("/cam0/pose", None), ("/cam1/pose", None)]
    local = read_log_streams(path, requests)
    with session((), 10.0, 2) as s:
        remote = read_log_streams(f"s3://{BUCKET}/bags/img.bag", requests)
    assert not s.notes and bound < 0.05 * path.stat().st_size
    assert bound <= s.bytes_fetched <= 1.2 * bound
    for x, y in zip(local, remote, strict=True):
        assert len(x) == 1000 and not y.warnings
        assert np.array_equal(x.stamps_ns, y.stamps_ns) and np.array_equal(x.xyz, y.xyz)
        assert np.array_equal(x.quat_xyzw, y.quat_xyzw)


def test_ros1_bag_by_range_with_tf_equals_local(s3, capsys):
    """The sample bag (TF, odometry, covariance poses) by range: the calibration and inspect equal the local ones."""
    flags = ("--topic-a", "/cam0/odom", "--topic-b", "/cam1/pose", "-q")
    code, local, _ = run(capsys, "calibrate", SAMPLES / "rig_ros1.bag", *flags)
    code_r, remote, err = run(capsys, "calibrate", f"s3://{BUCKET}/bags/rig_ros1.bag", *flags)
    assert code == code_r == 0, err
    _same_result(_doc(local), _doc(remote))
    assert not any("cache" in w for w in _doc(remote)["warnings"])
    frames = ("--frames-a", "world", "cam0", "--frames-b", "world", "cam1")
    texts = [run(capsys, "calibrate", p, *frames, "-q")[1] for p in (SAMPLES / "rig_ros1.bag",
                                                                     f"s3://{BUCKET}/bags/rig_ros1.bag")]
    _same_result(*map(_doc, texts))
    info = [json.loads(run(capsys, "inspect", p, "--format", "json")[1])
            for p in (SAMPLES / "rig_ros1.bag", f"s3://{BUCKET}/bags/rig_ros1.bag")]
    assert info[0]["topics"] == info[1]["topics"] and info[0]["start_ns"] == info[1]["start_ns"]


@pytest.mark.parametrize("damage", ["never indexed", "cut short"])
def test_a_ros1_bag_without_a_usable_index_is_downloaded_once(s3, tmp_path, damage):
    import struct

    import numpy as np

    from handeye_cli.io import read_log_streams
    from handeye_cli.io.remote import session

    data = bytearray((SAMPLES / "rig_ros1.bag").read_bytes())
    at = data.index(b"index_pos=") + len(b"index_pos=")
    (index_pos,) = struct.unpack_from("<Q", data, at)
    if damage == "never indexed":
        data[at:at + 8] = bytes(8)
    data = data[:index_pos]
    (tmp_path / "bad.bag").write_bytes(bytes(data))
    boto3.client("s3").put_object(Bucket=BUCKET, Key="bags/bad.bag", Body=bytes(data))
    requests = [("/cam0/odom", None), ("/cam1/pose", None)]
    local = read_log_streams(tmp_path / "bad.bag", requests)
    with session((), 10.0, 2) as s:
        remote = read_log_streams(f"s3://{BUCKET}/bags/bad.bag", requests)
    assert s.bytes_fetched >= len(data)
    why = "it was never indexed" if damage == "never indexed" else "past the end of the object"
    assert any(why in w and "downloaded it whole" in w for w in remote[0].warnings), remote[0].warnings
    assert any("linear scan" in w for w in remote[0].warnings)
    for x, y in zip(local, remote, strict=True):
        assert np.array_equal(x.stamps_ns, y.stamps_ns) and np.array_equal(x.xyz, y.xyz)


def test_planned_ranges_near_ones_joined_far_ones_apart_and_asked_ahead():
    """Ranges ≤ 64 KiB apart are one request (the gap counted), a far one its own; the views hold the
    object's bytes whichever request brought them, and the requests ahead are all answered by the end."""
    import fsspec

    from handeye_cli.io.remote import session
    from handeye_cli.io.remote.ranges import _GAP

    data = bytes(range(256)) * (1 << 13)                  # 2 MiB
    with fsspec.open("memory://ranges/obj.bin", "wb") as f:
        f.write(data)
    planned = [(1000, 100), (1100 + _GAP, 50), (1 << 20, 4000), ((1 << 21) - 10, 10)]
    with session((), 10.0, 2) as s:
        obj = s.open("memory://ranges/obj.bin")
        with obj.ranges(planned) as ranges:
            views = [bytes(ranges.view(a, n)) for a, n in planned]
        assert views == [data[a:a + n] for a, n in planned]
        assert s.requests == 3 and s.bytes_fetched == (100 + _GAP + 50) + 4000 + 10
        assert bytes(obj.ranges([]).view(5, 3)) == data[5:8] and s.requests == 4     # outside a plan: alone


@contextlib.contextmanager
def _served(tmp_path, mode: str = "", after: int = 1 << 62):
    """A plain HTTP range server on 127.0.0.1 (benchmarks/remote.py's) serving ``tmp_path``: its
    ``log`` holds (method, range, requests under way when it came) of every request. ``mode``
    "overlap": each range request waits (at most 0.5 s) until another request is under way, so that
    requests sent one after another are seen one at a time, and requests sent together together;
    "fail": ranges from byte ``after`` on are answered 500; "stall": they are never answered;
    "ignore": Range is ignored (200, the whole object). A context manager: shut down and closed on exit."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from remote import RangeHandler, http_server

    class Handler(RangeHandler):
        def _answer(self, path):
            server, asked = self.server, self.headers.get("Range", "")
            start = int(asked[6:].split("-")[0] or -1) if asked.startswith("bytes=") else -1
            if mode == "ignore":
                del self.headers["Range"]           # answers 200 with the whole object
            elif mode == "overlap" and asked:
                waited = time.monotonic()
                while server.active < 2 and time.monotonic() - waited < 0.5:
                    time.sleep(0.002)
            elif mode and start >= after:
                if mode == "fail":
                    self.send_error(500)
                    return None
                time.sleep(30)
                return None
            return super()._answer(path)

    with http_server(tmp_path, handler=Handler) as server:
        yield server, f"http://127.0.0.1:{server.server_address[1]}"


def test_planned_ranges_go_in_several_requests_at_once_with_the_serial_bytes(tmp_path):
    """Far-apart ranges: each its own request, several under way at once (the server saw more than
    one in flight), the views equal to the object's bytes in the planned order; a span of _AHEAD
    bytes or more is the only one asked for ahead."""
    from handeye_cli.io import remote

    data = np.random.default_rng(1).bytes(3 << 20)
    (tmp_path / "obj.bin").write_bytes(data)
    with _served(tmp_path, "overlap") as (server, base):
        planned = [(k * (200 << 10), 5000 + k) for k in range(12)]
        with remote.session((), 10.0, 2) as s:
            obj = s.open(f"{base}/obj.bin")
            with obj.ranges(planned) as ranges:
                views = [bytes(ranges.view(a, n)) for a, n in planned]
        assert views == [data[a:a + n] for a, n in planned]
        gets = [log for log in server.log if log[0] == "GET"]
        assert len(gets) == len(planned) and max(active for *_, active in gets) >= 2
        assert s.bytes_fetched == sum(n for _, n in planned)


def test_ranges_ahead_are_bounded_by_bytes(tmp_path, monkeypatch):
    """With _AHEAD at two spans, at most two requests are ever under way, and the bytes are right."""
    from handeye_cli.io import remote
    from handeye_cli.io.remote import ranges as ranges_module  # where Ranges reads _AHEAD

    data = np.random.default_rng(2).bytes(1 << 20)
    (tmp_path / "obj.bin").write_bytes(data)
    with _served(tmp_path, "overlap") as (server, base):
        planned = [(k * (100 << 10), 30_000) for k in range(8)]
        monkeypatch.setattr(ranges_module, "_AHEAD", 2 * 30_000)
        with remote.session((), 10.0, 2) as s, s.open(f"{base}/obj.bin").ranges(planned) as ranges:
            views = [bytes(ranges.view(a, n)) for a, n in planned]
        assert views == [data[a:a + n] for a, n in planned]
        assert max(active for method, _, active in server.log if method == "GET") == 2


def test_an_mcap_over_http_asks_size_head_and_tail_at_once_then_the_chunks_together(tmp_path):
    """Poses in their own chunks, by plain HTTP: the size, the first and the last bytes are three
    requests under way together (no folder listing, no separate footer request), the pose chunks
    go several at once, and the streams equal the local read."""
    from handeye_cli.io import read_log_streams
    from handeye_cli.io.remote import session

    sys.path.insert(0, str(ROOT / "benchmarks"))
    from remote import write_image_log

    path = write_image_log(tmp_path / "img.mcap", seconds=8, image_bytes=20_000, own_chunks=True)
    with _served(tmp_path, "overlap") as (server, base):
        requests = [("/cam0/pose", None), ("/cam1/pose", None)]
        with session((), 10.0, 2) as s:
            remote = read_log_streams(f"{base}/img.mcap", requests)
        local = read_log_streams(path, requests)
        for x, y in zip(local, remote, strict=True):
            assert np.array_equal(x.stamps_ns, y.stamps_ns) and np.array_equal(x.xyz, y.xyz)
            assert np.array_equal(x.quat_xyzw, y.quat_xyzw)
        first = server.log[:3]
        assert sorted(r or "" for _, r, _ in first) == ["", "bytes=-16384", "bytes=0-4095"]
        assert max(active for *_, active in first) >= 2 and "HEAD" in [m for m, *_ in first]
        chunks = server.log[3:]
        assert len(chunks) == 8 and max(active for *_, active in chunks) >= 2 and s.requests == 2 + 8


@pytest.mark.parametrize("mode", ["fail", "stall"])
def test_a_chunk_request_that_fails_or_stalls_is_one_line(tmp_path, capsys, mode):
    """The size, head and tail answered, then every chunk request failing (500) or never answered:
    exit 2 and one line naming the URL, after the bounded tries (no hang)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from remote import write_image_log

    write_image_log(tmp_path / "img.mcap", seconds=4, image_bytes=20_000, own_chunks=True)
    with _served(tmp_path, mode, after=4096) as (server, base):
        code, out, err = run(capsys, "calibrate", f"{base}/img.mcap", *TOPICS, "-q", "--remote-timeout", "0.5",
                             "--remote-retries", "2")
        assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
        assert f"{base}/img.mcap" in err and "failed 2 times" in err
        assert ("no answer in time" in err) == (mode == "stall")


def test_over_plain_http_a_missing_object_and_a_server_ignoring_ranges_are_one_line(tmp_path, capsys):
    """404: "no such object" at once; a server answering a Range request with the whole object: a
    clear line, never those bytes taken for the range."""
    (tmp_path / "rig.mcap").write_bytes((SAMPLES / "rig.mcap").read_bytes())
    with _served(tmp_path) as (server, base):
        code, out, err = run(capsys, "calibrate", f"{base}/missing.mcap", *TOPICS, "-q")
        assert code == 2 and out == "" and err.startswith("error: no such object") and len(err.splitlines()) == 1
    with _served(tmp_path, "ignore") as (server, base):
        code, out, err = run(capsys, "calibrate", f"{base}/rig.mcap", *TOPICS, "-q")
        assert code == 2 and out == "" and "ignores byte ranges (answered 200" in err and len(err.splitlines()) == 1
        assert len(server.log) <= 4                 # no retries of a wrong answer


class _Store:
    """A file system holding one 100-byte object whose range reads raise ``error`` (its size answers)."""

    def __init__(self, error: BaseException) -> None:
        self.error = error

    def info(self, path: str) -> dict[str, object]:
        return {"type": "file", "size": 100}

    def cat_file(self, path: str, start: int = 0, end: int | None = None) -> bytes:
        raise self.error


@pytest.mark.parametrize("error", [OSError("connection reset"), KeyError("a bug in a reader")])
def test_a_failed_read_ahead_is_asked_again_but_a_bug_is_not_hidden(monkeypatch, error):
    """Issue 37: the read-ahead beside the size turned every exception into 'no bytes' (None), a bug too. A
    request that failed (a one-line ReadError of Session.call: the network, a missing object) is None, and
    the reader asks again with its retries; any other exception reaches the caller as itself (exit 4)."""
    from handeye_cli.errors import ReadError
    from handeye_cli.io import remote

    store = _Store(error)
    monkeypatch.setattr(remote.Session, "fs", lambda self, url, listing=False: (store, url))
    url = "s3://bucket/obj.mcap"
    with remote.session((), 1.0, 1) as s:
        assert not s.is_folder(url, read_ahead=True)
        if isinstance(error, OSError):
            obj = s.open(url)                              # nothing held: the reader's requests say what is wrong
            assert obj.held(0, 10) is None
            with pytest.raises(ReadError, match="failed 1 times"):
                obj.fetch(0, 10)
        else:
            with pytest.raises(KeyError, match="a bug in a reader"):
                s.open(url)


def test_a_stalled_object_fails_at_its_deadline_whatever_the_retries(capsys):
    """Issue 36: every request of an object stalling, 0.5 s × 5 tries would take > 2.5 s (30 s × 4 by default:
    > 120 s); the object's deadline of 1.5 s without an answer ends it: exit 2, one line naming the URL, the
    deadline and the requests tried."""
    start = time.monotonic()
    with _silent_server() as port:
        url = f"http://127.0.0.1:{port}/stalled.mcap"
        code, out, err = run(capsys, "calibrate", url, *TOPICS, "-q", "--remote-timeout", "0.5", "--remote-retries",
                             "5", "--remote-deadline", "1.5")
        took = time.monotonic() - start
    assert 1.4 < took < 4, took
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert url in err and "no progress for 1.5 s (" in err and "requests tried)" in err, err
    assert "--remote-deadline" in err and int(err.split("no progress for 1.5 s (")[1].split()[0]) >= 2


def test_a_batch_gives_the_stalled_object_its_error_record_and_reads_the_others(tmp_path, capsys):
    """A batch of a stalled URL and a good one: the stalled one's record is an error naming its deadline, the
    good one's is ok; exit 2."""
    (tmp_path / "rig.mcap").write_bytes((SAMPLES / "rig.mcap").read_bytes())
    start = time.monotonic()
    with _served(tmp_path) as (_, base), _silent_server() as port:
        stalled = f"http://127.0.0.1:{port}/stalled.mcap"
        code, out, err = run(capsys, "batch", stalled, f"{base}/rig.mcap", *TOPICS, "-q", "--jobs", "1",
                             "--remote-timeout", "0.5", "--remote-retries", "5", "--remote-deadline", "1")
        took = time.monotonic() - start
    records = {r["input"]: r for r in map(json.loads, out.splitlines())}
    assert code == 2 and set(records) == {stalled, f"{base}/rig.mcap"}, (out, err)
    assert records[f"{base}/rig.mcap"]["status"] == "ok"
    bad = records[stalled]
    assert bad["status"] == "error" and "no progress for 1 s (" in bad["error"] and "\n" not in bad["error"]
    assert "remote-deadline" in bad["error"] and took < 5, took


def test_a_slow_object_that_keeps_answering_is_never_cut(tmp_path):
    """The deadline is time without an answered request: each answer (0.2 s late) stops the clock, so eight
    requests in a row (1.6 s) and a pause of the reader longer than the deadline (decoding) pass a deadline of
    0.4 s; an answer later than the deadline is the deadline's line."""
    from handeye_cli.errors import ReadError
    from handeye_cli.io import remote

    sys.path.insert(0, str(ROOT / "benchmarks"))
    from remote import http_server

    data = np.random.default_rng(3).bytes(1 << 20)
    (tmp_path / "obj.bin").write_bytes(data)
    with http_server(tmp_path, latency=0.2) as server:
        url = f"http://127.0.0.1:{server.server_address[1]}/obj.bin"
        start = time.monotonic()
        with remote.session((), 5.0, 1, 0.4) as s:
            obj = s.open(url)
            got = [obj.fetch(k << 17, (k << 17) + 1000) for k in range(8)]
            time.sleep(0.5)                             # the reader busy: no request under way, no clock
            got.append(obj.fetch(5, 10))
        assert time.monotonic() - start > 0.4 * 4 and s.requests == 9
        assert got == [data[k << 17:(k << 17) + 1000] for k in range(8)] + [data[5:10]]
        server.latency = 0.6
        late = pytest.raises(ReadError, match=r"no progress for 0.4 s \(1 request tri")
        with remote.session((), 5.0, 3, 0.4) as s, late:
            s.open(url)
