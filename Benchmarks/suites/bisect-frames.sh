# Which commit made the frames slower: gpu_render_benchmark built at each commit given (git
# archive, in parallel, 4 jobs each) and the benchmark scenes run twice per build, alternating.
# How the traversal regression of e7b64c6 was found (RESULTS-archive.md, "GPU DDA traversal").
#   bench.sh bisect-frames --out DIR -- COMMIT...
SUITE_ABOUT="frames at several commits: gpu_render_benchmark built per commit, scenes run twice, alternating"
SUITE_COST="a build per commit (in parallel) + about 1 min per commit on one H100"
SUITE_NEEDS="GPU"
SUITE_BEFORE=none
SUITE_HELP='(-- COMMIT ...: the commits to compare)'

suite_run() {
  [ $# -gt 0 ] || { echo "bisect-frames: name the commits after --" >&2; return 2; }
  local c r B W R=Testing/Data/real
  W=$(mktemp -d)
  bench_gpu_name
  stamp "builds"
  for c in "$@"; do
    git rev-parse --verify --quiet "$c^{commit}" > /dev/null || { echo "bisect-frames: $c names no commit" >&2; return 2; }
    (
      bench_source_of "$c" "$W/src-$c"
      bench_configure "$W/src-$c" "$W/src-$c/b" -DINR_BUILD_TESTS=OFF > "$W/cfg-$c.log" 2>&1
      x ninja -C "$W/src-$c/b" -j4 gpu_render_benchmark > "$W/build-$c.log" 2>&1 || { echo "build $c failed"; tail -20 "$W/build-$c.log"; }
    ) &
  done
  wait
  stamp "frames, two runs per commit"
  for r in 1 2; do for c in "$@"; do
    B=$W/src-$c/b/Benchmarks/gpu_render_benchmark
    echo "== $c run $r"
    x "$B" --no-paper --no-baselines --frames 30 $R/siren_cylinder_vorticity.inr $R/ffn_mri_head.inr 2>&1 \
      | tee "$OUT/bench_${c}_$r.txt" | grep "^4b"
  done; done
  rm -rf "$W"
}
