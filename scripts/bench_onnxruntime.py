#!/usr/bin/env python3
"""onnxruntime side of the tract comparison for the `arbitrary` stylizer.

Bench mode (prints JSON on stdout):
    bench_onnxruntime.py MODELS_DIR SIZE REPS [--threads N]
  times arbitrary_predict.onnx on a 1x256x256x3 input and arbitrary_transform.onnx on a
  1xSIZExSIZEx3 input (median of REPS runs after one warm-up), with N intra-op threads
  (default 2, the same as tract on these machines).

Reference mode (used by the tract-vs-onnxruntime test):
    bench_onnxruntime.py --run MODELS_DIR REQUEST.json [--threads N]
  REQUEST.json is a list of {"model": FILE, "inputs": [{"file": F, "shape": [...]}, ...],
  "output": F}; each input file holds raw little-endian float32 values, fed by position;
  the first output is written to "output" as raw float32.

Exit status 3 (with a JSON error) when onnxruntime or numpy cannot be imported.
"""
import json
import os
import statistics
import sys
import time


def fail(code, msg):
    print(json.dumps({"error": msg}))
    sys.exit(code)


try:
    import numpy as np
    import onnxruntime as ort
except Exception as exc:  # ImportError, or a broken install
    fail(3, f"onnxruntime/numpy not importable: {exc}")


def session(path, threads):
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = threads
    opts.inter_op_num_threads = 1
    opts.log_severity_level = 3
    return ort.InferenceSession(path, opts, providers=["CPUExecutionProvider"])


def timed(fn, reps):
    fn()  # warm-up
    times = []
    for _ in range(max(1, reps)):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def bench(models_dir, size, reps, threads):
    t0 = time.perf_counter()
    pred = session(os.path.join(models_dir, "arbitrary_predict.onnx"), threads)
    trans = session(os.path.join(models_dir, "arbitrary_transform.onnx"), threads)
    create_s = time.perf_counter() - t0
    style = np.full((1, 256, 256, 3), 0.5, dtype=np.float32)
    content = np.full((1, size, size, 3), 0.5, dtype=np.float32)
    p_in = pred.get_inputs()[0].name
    emb = pred.run(None, {p_in: style})[0].astype(np.float32)
    t_names = [i.name for i in trans.get_inputs()]
    feed = {t_names[0]: content, t_names[1]: emb}
    t0 = time.perf_counter()
    trans.run(None, feed)
    first_s = time.perf_counter() - t0
    result = {
        "onnxruntime_version": ort.__version__,
        "threads": threads,
        "size": size,
        "reps": reps,
        "session_create_s": create_s,
        "transform_first_s": first_s,
        "predict_median_s": timed(lambda: pred.run(None, {p_in: style}), reps),
        "transform_median_s": timed(lambda: trans.run(None, feed), reps),
    }
    print(json.dumps(result))


def run_requests(models_dir, request_path, threads):
    with open(request_path) as f:
        tasks = json.load(f)
    base = os.path.dirname(os.path.abspath(request_path))
    for task in tasks:
        sess = session(os.path.join(models_dir, task["model"]), threads)
        feed = {}
        for meta, spec in zip(sess.get_inputs(), task["inputs"]):
            data = np.fromfile(os.path.join(base, spec["file"]), dtype="<f4")
            feed[meta.name] = data.reshape(spec["shape"])
        out = sess.run(None, feed)[0].astype("<f4")
        out.tofile(os.path.join(base, task["output"]))
    print(json.dumps({"ok": len(tasks)}))


def main(argv):
    threads = 2
    if "--threads" in argv:
        i = argv.index("--threads")
        threads = int(argv[i + 1])
        del argv[i : i + 2]
    if argv and argv[0] == "--run":
        if len(argv) != 3:
            fail(2, "usage: bench_onnxruntime.py --run MODELS_DIR REQUEST.json [--threads N]")
        run_requests(argv[1], argv[2], threads)
        return
    if len(argv) != 3:
        fail(2, "usage: bench_onnxruntime.py MODELS_DIR SIZE REPS [--threads N]")
    bench(argv[0], int(argv[1]), int(argv[2]), threads)


if __name__ == "__main__":
    main(sys.argv[1:])
