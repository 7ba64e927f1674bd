# A video between two photos with any UP-LVSM checkpoint, from Python:
#   python3 render_two_photos.py CHECKPOINT A.jpg B.jpg OUT.mp4
import sys

import torch
import uplvsm

checkpoint, photo_a, photo_b, out = sys.argv[1:5]
model = uplvsm.load(checkpoint)  # the authors' .pt/.safetensors or a uplvsm run
photos = uplvsm.data.load_photos([photo_a, photo_b], image_size=model.config["model"]["image_size"], fov=60.0)
with torch.no_grad():
    video = model.render_interpolation(photos["images"], photos["fxfycxcy"], num_frames=24)
uplvsm.io.write_mp4(out, video["frames"], fps=12)
print(f"wrote {len(video['frames'])} frames to {out}")
