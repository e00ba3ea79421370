"""The libFuzzer harness of the C engine (engine/fuzz/fuzz_engine.c), a bounded smoke run per build.

Both precisions are built with clang's -fsanitize=fuzzer,address,undefined into a temporary
directory and run for SECONDS each from a seed corpus of small table images (engine/fuzz/seeds.py
wraps them): no sanitizer report, no failed check of the harness (a load is SD_OK or an
SD_ERR_IMAGE_* code, loaded values finite, every output finite, drive and audio in [-1, 1]).
`make -C shapedisplay/engine fuzz` is the long run. Skipped where clang cannot link libFuzzer
(Debian: libclang-rt-dev, scripts/install-system-deps.sh --with-toolchains).
"""
import importlib.util
import re
import shutil
import subprocess

import pytest

from test_c_runtime import CDIR, CFLAGS, LIB, widget_table

SECONDS = 20                 # per build (the brief's bound is 30)
FUZZ_FLAGS = ["-g", "-fsanitize=fuzzer,address,undefined", "-fno-sanitize-recover=all"]
SINGLE = ["-DSD_SINGLE", "-Wdouble-promotion", "-Wfloat-conversion"]


def _libfuzzer_missing(tmp) -> str | None:
    if not shutil.which("clang"):
        return "clang is not installed"
    src = tmp / "probe.c"
    src.write_text("#include <stddef.h>\n#include <stdint.h>\n"
                   "int LLVMFuzzerTestOneInput(const uint8_t *d, size_t n) { (void)d; (void)n; return 0; }\n")
    res = subprocess.run(["clang", *FUZZ_FLAGS, str(src), "-o", str(tmp / "probe")], capture_output=True, text=True,
                         timeout=120)
    return None if res.returncode == 0 else "clang cannot link -fsanitize=fuzzer (libclang-rt-dev): " + res.stderr[-200:]


@pytest.fixture(scope="module")
def fuzz_dir(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("fuzz")
    why = _libfuzzer_missing(tmp)
    if why:
        pytest.skip(why)
    from shapedisplay.render import image as I
    spec = importlib.util.spec_from_file_location("fuzz_seeds", CDIR / "fuzz" / "seeds.py")
    seeds = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(seeds)
    images = []
    from runtime_vectors import reactive_table      # a version 2 image: reactive widgets and moving parts
    for i, table in enumerate((widget_table("uint16"), widget_table("uint8"), widget_table("float32", sparse=False),
                               reactive_table())):
        path = tmp / f"widgets{i}.sdt"
        path.write_bytes(I.to_image(table))
        images.append(str(path))
    seeds.main(str(tmp / "seeds"), images)
    return tmp


@pytest.mark.parametrize("precision", ["double", "single"])
def test_fuzz_engine_smoke_run(fuzz_dir, precision):
    exe = fuzz_dir / f"fuzz_engine_{precision}"
    srcs = [str(CDIR / n) for n in LIB] + [str(CDIR / "fuzz" / "fuzz_engine.c")]
    cmd = ["clang", *CFLAGS, *(SINGLE if precision == "single" else []), *FUZZ_FLAGS, "-I", str(CDIR), *srcs,
           "-lm", "-o", str(exe)]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-3000:]
    corpus = fuzz_dir / f"corpus-{precision}"
    corpus.mkdir()
    res = subprocess.run([str(exe), f"-max_total_time={SECONDS}", "-timeout=10", "-rss_limit_mb=2048",
                          "-print_final_stats=1", f"-artifact_prefix={fuzz_dir}/crash-{precision}-",
                          str(corpus), str(fuzz_dir / "seeds")],
                         capture_output=True, text=True, timeout=SECONDS + 120)
    assert res.returncode == 0, res.stderr[-4000:]
    runs = int(re.search(r"stat::number_of_executed_units: (\d+)", res.stderr).group(1))
    assert runs > 100, res.stderr[-2000:]
