"""The peer of `cargo bench --bench perception -- whole_view`: the same
YOLO11n ONNX file in ONNX Runtime's own Python API (the version
tests/fixtures/requirements.txt pins), 2 intra-op threads, one 640x640
input made beforehand; the median of 300 runs, in ms.

    OPENNAV_SHARED=../shared .venv/bin/python benches/ort_python_yolo11n.py
"""

import os
import statistics
import time

import numpy as np
import onnxruntime as ort

shared = os.environ.get("OPENNAV_SHARED", os.path.join(os.path.dirname(__file__), "..", "..", "shared"))
model = os.path.join(shared, "models", "yolo11n_coco.onnx")
opts = ort.SessionOptions()
opts.intra_op_num_threads = 2
sess = ort.InferenceSession(model, opts, providers=["CPUExecutionProvider"])
name = sess.get_inputs()[0].name
x = np.random.default_rng(0).random((1, 3, 640, 640), dtype=np.float32)
for _ in range(20):
    sess.run(None, {name: x})
times = []
for _ in range(300):
    t = time.perf_counter()
    sess.run(None, {name: x})
    times.append((time.perf_counter() - t) * 1e3)
print(f"onnxruntime {ort.__version__} python, yolo11n, 2 threads: median {statistics.median(times):.2f} ms")
