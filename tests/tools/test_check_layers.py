# tools/check_layers.py (run by `make lint`): the repository's includes run down the layer order, and the checker
# catches an include that runs up it (in the library, in a test, through a test helper), kernels reaching past core,
# a public header reaching a private room, an exception that no longer matches any include, and a file whose code
# lives in another room's namespace than its folder's.
import importlib.util
import os
import pathlib

REPO = pathlib.Path(os.environ.get("UPLVSM_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
spec = importlib.util.spec_from_file_location("check_layers", REPO / "tools" / "check_layers.py")
check_layers = importlib.util.module_from_spec(spec)
spec.loader.exec_module(check_layers)


def tree(root, files):
    """Writes {path: included headers} under root: each file a list of #include lines."""
    for path, includes in files.items():
        target = root / path
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text("".join(f'#include "{i}"\n' for i in includes))
    return root


CLEAN = {
    "src/uplvsm/core/config.h": [],
    "src/uplvsm/kernels/ops.h": ["uplvsm/core/config.h"],
    "src/uplvsm/model/transformer.h": ["uplvsm/core/config.h"],
    "src/uplvsm/model/transformer.cpp": ["uplvsm/model/transformer.h", "uplvsm/kernels/ops.h"],
    "src/uplvsm/train/trainer.h": ["uplvsm/model/transformer.h"],
    "src/uplvsm/cli/main.cpp": ["uplvsm/train/trainer.h", "uplvsm/uplvsm.h"],
    "tests/test_util.h": ["uplvsm/core/config.h"],
    "tests/train/train_test_util.h": ["test_util.h", "uplvsm/train/trainer.h"],
    "tests/model/transformer_test.cpp": ["test_util.h", "uplvsm/model/transformer.h"],
    "bench/train_bench.cpp": ["uplvsm/train/trainer.h"],
}


def test_the_repository_follows_the_order():
    assert check_layers.check(REPO) == []


def test_a_clean_tree_passes(tmp_path):
    assert check_layers.check(tree(tmp_path, CLEAN), exceptions=[]) == []


def offences(tmp_path, path, include, exceptions=()):
    files = dict(CLEAN)
    files[path] = files.get(path, []) + [include]
    return check_layers.check(tree(tmp_path, files), exceptions=list(exceptions))


def test_an_include_up_the_order_fails(tmp_path):
    errors = offences(tmp_path, "src/uplvsm/model/transformer.cpp", "uplvsm/train/trainer.h")
    assert errors == ['src/uplvsm/model/transformer.cpp:3: #include "uplvsm/train/trainer.h" (train is not below model)']


def test_a_sibling_room_fails(tmp_path):
    errors = offences(tmp_path, "src/uplvsm/eval/evaluator.cpp", "uplvsm/train/trainer.h")
    assert len(errors) == 1 and "train is not below eval" in errors[0]


def test_kernels_include_core_only(tmp_path):
    errors = offences(tmp_path, "src/uplvsm/kernels/ops.cpp", "uplvsm/io/safetensors.h")
    assert len(errors) == 1 and "kernels includes only core" in errors[0]


def test_a_public_header_includes_no_private_room(tmp_path):
    errors = offences(tmp_path, "src/uplvsm/model/linear.h", "uplvsm/kernels/ops.h")
    assert len(errors) == 1 and "kernels is private" in errors[0]
    assert offences(tmp_path / "source", "src/uplvsm/model/linear.cpp", "uplvsm/kernels/ops.h") == []


def test_tests_are_held_to_their_room_and_helpers_count(tmp_path):
    errors = offences(tmp_path, "tests/model/transformer_test.cpp", "uplvsm/train/trainer.h")
    assert len(errors) == 1 and errors[0].startswith("tests/model/transformer_test.cpp:3:")
    errors = offences(tmp_path / "helper", "tests/model/transformer_test.cpp", "train/train_test_util.h")
    assert len(errors) == 1 and "train is not below model" in errors[0]


def test_a_listed_exception_allows_and_a_stale_one_fails(tmp_path):
    exception = ("tests/model/*", "uplvsm/train/*", "why")
    assert offences(tmp_path, "tests/model/transformer_test.cpp", "uplvsm/train/trainer.h", [exception]) == []
    errors = check_layers.check(tree(tmp_path / "clean", CLEAN), exceptions=[exception])
    assert len(errors) == 1 and "matches no include" in errors[0]


def namespace_errors(tmp_path, path, text):
    tree(tmp_path, CLEAN)
    (tmp_path / path).parent.mkdir(parents=True, exist_ok=True)
    (tmp_path / path).write_text(text)
    return check_layers.check(tmp_path, exceptions=[])


def block(name, body):
    return f"namespace {name} {{\n{body}\n}}  // namespace {name}\n"


def test_a_file_declares_its_code_in_its_folders_namespace(tmp_path):
    errors = namespace_errors(tmp_path / "a", "src/uplvsm/train/flops.h", block("uplvsm::model", "int flops();"))
    assert errors == ["src/uplvsm/train/flops.h: namespace uplvsm::model in train/ (its namespace is uplvsm::train)"]
    assert namespace_errors(tmp_path / "b", "src/uplvsm/train/flops.h", block("uplvsm::train", "int flops();")) == []
    nested = block("uplvsm::kernels::flash", "int tile();")
    assert namespace_errors(tmp_path / "c", "src/uplvsm/kernels/flash.h", nested) == []


def test_another_rooms_namespace_only_to_forward_declare(tmp_path):
    text = block("uplvsm::model", "struct UPLVSMImpl;\n// the model") + block("uplvsm::serve", "int serve();")
    assert namespace_errors(tmp_path, "src/uplvsm/serve/viewer_model.h", text) == []


def test_core_lives_in_uplvsm_itself(tmp_path):
    assert namespace_errors(tmp_path / "a", "src/uplvsm/core/config.h", block("uplvsm", "struct Config {};")) == []
    assert namespace_errors(tmp_path / "b", "src/uplvsm/core/ssim.h", block("uplvsm::ssim", "int w();")) == []
    errors = namespace_errors(tmp_path / "c", "src/uplvsm/core/eval_mode.h", block("uplvsm::model", "struct G {};"))
    assert len(errors) == 1 and "its namespace is uplvsm)" in errors[0]
