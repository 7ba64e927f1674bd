# A stand-in for einops (rearrange / repeat over named and parenthesised axes) so that bench/official_x224.py can
# import the authors' model where the real package cannot be installed; developer benchmarks only.
import math
import torch

def _parse(side):
    groups, cur, depth = [], None, 0
    for tok in side.replace("(", " ( ").replace(")", " ) ").split():
        if tok == "(":
            cur = []
        elif tok == ")":
            groups.append(cur); cur = None
        elif cur is not None:
            cur.append(tok)
        else:
            groups.append([tok])
    return groups

def _sizes(groups, shape, known):
    sizes = dict(known)
    assert len(groups) == len(shape), (groups, shape)
    for g, n in zip(groups, shape):
        unknown = [a for a in g if a not in sizes]
        prod = math.prod(sizes[a] for a in g if a in sizes)
        if len(unknown) == 1:
            sizes[unknown[0]] = n // prod
        elif unknown:
            raise ValueError(f"cannot infer {unknown}")
    return sizes

def _apply(x, pattern, expand, **known):
    left, right = [s.strip() for s in pattern.split("->")]
    lg, rg = _parse(left), _parse(right)
    sizes = _sizes(lg, x.shape, known)
    lax = [a for g in lg for a in g]
    x = x.reshape([sizes[a] for a in lax])
    rax = [a for g in rg for a in g]
    new = [a for a in rax if a not in lax]
    if new and not expand:
        raise ValueError(f"new axes {new} in rearrange")
    kept = [a for a in rax if a in lax]
    x = x.permute([lax.index(a) for a in kept])
    for i, a in enumerate(rax):
        if a in new:
            x = x.unsqueeze(i)
    x = x.expand([sizes[a] for a in rax])
    return x.reshape([math.prod(sizes[a] for a in g) for g in rg])

def rearrange(x, pattern, **sizes):
    return _apply(x, pattern, False, **sizes)

def repeat(x, pattern, **sizes):
    return _apply(x, pattern, True, **sizes)
