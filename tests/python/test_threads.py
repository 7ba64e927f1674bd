# The GIL is released while the model runs: two Python threads render with one model at once (each gets the serial
# result), and the main thread keeps running Python meanwhile.
import threading
import time

import torch
import uplvsm

from conftest import OFFICIAL


def test_two_threads_render_concurrently():
    model = uplvsm.load(str(OFFICIAL / "checkpoint.pt"))
    images = torch.rand(2, 3, 126, 126, generator=torch.Generator().manual_seed(0))
    fxfycxcy = torch.tensor([[110.0, 110.0, 63.0, 63.0]] * 2)
    serial = model.render_interpolation(images, fxfycxcy, num_frames=24)["frames"]  # also warms the thread pools

    results, spans, barrier = {}, {}, threading.Barrier(3)

    def render(name):
        barrier.wait()
        t0 = time.perf_counter()
        results[name] = model.render_interpolation(images, fxfycxcy, num_frames=24)["frames"]
        spans[name] = (t0, time.perf_counter())

    threads = [threading.Thread(target=render, args=(n,)) for n in ("a", "b")]
    for t in threads:
        t.start()
    barrier.wait()
    # While both render, this thread keeps running Python: with the GIL held by a render it would stall for a whole
    # render at a time.
    ticks = [time.perf_counter()]
    while any(t.is_alive() for t in threads):
        time.sleep(0.002)  # leave the cores to the renders
        ticks.append(time.perf_counter())
    for t in threads:
        t.join()
    assert torch.equal(results["a"], serial) and torch.equal(results["b"], serial)
    longest_stall = max(b - a for a, b in zip(ticks, ticks[1:]))
    render_time = min(end - begin for begin, end in spans.values())
    assert longest_stall < 0.5 * render_time, (longest_stall, render_time)
    # Both renders were in C++ at the same time: each began before the other ended.
    assert spans["a"][0] < spans["b"][1] and spans["b"][0] < spans["a"][1]
