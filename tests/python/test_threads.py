# The GIL is released while the model runs: two Python threads render with one model at once (each gets the serial
# result), and the main thread keeps running Python meanwhile. (A call that kept the GIL - checked by hand with
# ctypes.PyDLL(None).usleep(1_500_000) in place of the render - stalls the main thread for 3 s and the spans do not
# overlap.)
import threading
import time

import torch
import uplvsm

from conftest import OFFICIAL, needs_fixtures


@needs_fixtures
def test_two_threads_render_concurrently():
    model = uplvsm.load(str(OFFICIAL / "checkpoint.pt"))
    images = torch.rand(2, 3, 126, 126, generator=torch.Generator().manual_seed(0))
    fxfycxcy = torch.tensor([[110.0, 110.0, 63.0, 63.0]] * 2)
    serial = model.render_interpolation(images, fxfycxcy, num_frames=24)["frames"]  # also warms the thread pools

    results, spans = {}, {}

    def render(name):
        t0 = time.perf_counter()
        results[name] = model.render_interpolation(images, fxfycxcy, num_frames=24)["frames"]
        spans[name] = (t0, time.perf_counter())

    threads = [threading.Thread(target=render, args=(n,)) for n in ("a", "b")]
    # This thread ticks from before the renders start until both end: a render holding the GIL would leave a gap as
    # long as the render between two ticks.
    ticks = [time.perf_counter()]
    for t in threads:
        t.start()
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
