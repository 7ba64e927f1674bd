# Developer-only: RealEstate10K-sized pixelSplat chunks (~100 MB each) from the re10k_chunks fixture's JPEG frames,
# repeated, to time chunk parsing for the shuffling note in docs/training.md. Writes OUT/train/*.torch + index.json.
#   /usr/bin/python3 tools/make_re10k_sized_chunks.py FIXTURES OUT CHUNKS SCENES_PER_CHUNK FRAMES   (e.g. ... 8 30 150)
import glob, json, os, sys
import torch
fixtures, out = sys.argv[1], sys.argv[2]
src = torch.load(sorted(glob.glob(f'{fixtures}/re10k_chunks/root/train/*.torch'))[0])
frames = [im for s in src for im in s['images']]
cams = src[0]['cameras'][0]
n_chunks, scenes_per_chunk, n_frames = int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5])
os.makedirs(f'{out}/train', exist_ok=True)
index = {}
for c in range(n_chunks):
    chunk = []
    for s in range(scenes_per_chunk):
        key = f"{c:06x}{s:010x}"
        chunk.append({'url': 'synthetic://' + key, 'timestamps': torch.arange(n_frames, dtype=torch.int64) * 100000,
                      'cameras': cams.unsqueeze(0).repeat(n_frames, 1).clone(),
                      'images': [frames[(s * 7 + i) % len(frames)].clone() for i in range(n_frames)], 'key': key})
        index[key] = f"{c:06d}.torch"
    torch.save(chunk, f"{out}/train/{c:06d}.torch")
with open(f'{out}/train/index.json', 'w') as f:
    json.dump(index, f)
