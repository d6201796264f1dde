# Sub-domain rendering over the GPUs of one machine without MPI (issues 16 and 31): for each image
# size and each model, one single-GPU render on GPU 0 (the 1-GPU image and timing), then for each
# split and each N, N parts at once, one process per GPU (CUDA_VISIBLE_DEVICES), composited by
# composite_bricks.py and compared with the 1-GPU image; then one table, CSV and plot over all of
# them (brick_scaling_summary.py): frame time, time to 40 dB over the volume's pixels read from
# the per-frame estimates, frames, queries per GPU, the composite against the 1-GPU image,
# speed-up and efficiency.
# SPLIT: pixels (the plugin's image-space split, `inr render --pixel-share I/N`), samples
# (`--sample-share I/N`: every GPU renders every pixel of its own frames) or bricks (`--brick I/N`).
# The single run and the pixel or brick parts stop at an estimated PSNR of TARGET dB over the
# volume (or MAX_FRAMES). The sample shares render fixed frame counts instead: share I renders
# ceil((F - I) / N) frames, F the single run's, so together they render exactly its frames and
# their frame-weighted mean is the 1-GPU image up to rounding.
# BACKEND=cpu: CPU processes instead (a CPU build, no GPU): the single run uses every core, each of
# the N parallel ones nproc/N threads (CPU "ranks" on one machine).
# Output: OUT/scaling.txt (the table), OUT/scaling.csv, OUT/scaling.png, OUT/SIZE/ (per-run
# logs, statistics, composites).
SUITE_ABOUT="scaling over GPUs: pixel / sample / brick shares at N GPUs against one, time to 40 dB (inr render, composite_bricks.py)"
SUITE_COST="about 6 min on 4 H100s after the build (TARGET and MAX_FRAMES keep it there); BACKEND=cpu at SIZES=64: a minute"
SUITE_NEEDS="GPUs (N of them; BACKEND=cpu: CPU), python3 with numpy"
SUITE_BEFORE=rerun
SUITE_HELP='SIZES=1024 2048   image sizes (one folder each)
N=2 4             part counts (each needs that many GPUs)
SPLIT=pixels samples   splits: pixels, samples, bricks
TARGET=41         the single run stops at this estimated PSNR over the volume (past 40: every row has a time to 40 dB)
MAX_FRAMES=1500   ... or at this many frames
TIME=2            the model time rendered
BACKEND=cuda      cuda, or cpu (CPU processes, no GPU)
PYTHON=python3    the interpreter with numpy for the compositing (default: the first with numpy)
(-- MODEL.inr ...: the models; default coordnet_cylinder_u, ffn_mri_head, siren_cylinder_vorticity)'
SUITE_TABLES="scaling.txt"

suite_needs_gpu() { [ "${BACKEND:-cuda}" != cpu ]; }
suite_build() { bench_build inr; }

# scaling_at_size OUT SIZE MODEL...: the runs of one image size (what run_brick_scaling.sh did).
scaling_at_size() {
  local out=$1 size=$2
  shift 2
  mkdir -p "$out"
  local inr="$BUILD/bin/inr" backend=${BACKEND:-cuda} scratch split n i p t0 tag option model name tf whole_frames
  local common converge frames pids
  scratch=$(mktemp -d)  # the float images stay out of OUT (16 MB each at 1024^2)
  if [ "$backend" = cpu ]; then
    nproc | sed 's/^/cpu cores: /' | tee "$out/gpus.txt"
  else
    nvidia-smi --query-gpu=index,name,driver_version --format=csv,noheader | tee "$out/gpus.txt"
  fi
  # CPU threads of a run with `parts` processes at once (the CPU backend only).
  threads_for() {
    if [ "$backend" = cpu ]; then
      local per=$(($(nproc) / $1)); [ "$per" -ge 1 ] || per=1
      echo --threads "$per"
    fi
  }
  split_option() { case "$1" in pixels) echo --pixel-share ;; samples) echo --sample-share ;; bricks) echo --brick ;; esac; }
  ms_now() { echo $(($(date +%s%N) / 1000000)); }
  for model in "$@"; do
    name=$(basename "$model" .inr)
    tf="${model%.inr}.tf.json"
    common=(--time "${TIME:-2}" --size "${size}x${size}" --macrocells 64 --backend "$backend" --quiet)
    [ -f "$tf" ] && common+=(--tf "$tf")
    converge=(--converge "$TARGET" --frames "$MAX_FRAMES")
    echo "== $name: 1 GPU"
    t0=$(ms_now)
    # A 1/1 split is the plain renderer; it writes the .npy and .brick.json the compositing reads.
    # shellcheck disable=SC2046
    x env CUDA_VISIBLE_DEVICES=0 "$inr" render "$model" "${common[@]}" "${converge[@]}" $(threads_for 1) --pixel-share 0/1 \
      -o "$scratch/$name.whole.npy" --stats-json "$out/$name.whole.stats.json" | tail -2
    echo "wall $(($(ms_now) - t0)) ms" | tee "$out/$name.whole.wall"
    if [ "$DRY_RUN" = 1 ]; then
      whole_frames=F
    elif [ ! -f "$scratch/$name.whole.brick.json" ]; then
      echo "$name: the 1-GPU run failed; skipped"
      continue
    else
      cp "$scratch/$name.whole.brick.json" "$out/"
      whole_frames=$("$PYTHON" -c 'import json, sys; print(json.load(open(sys.argv[1]))["frames"])' \
        "$scratch/$name.whole.brick.json")
    fi
    for split in ${SPLIT//,/ }; do
      option=$(split_option "$split")
      for n in ${N//,/ }; do
        tag="$name.$split$n"
        echo "== $name: $n parts ($split) on $n GPUs"
        t0=$(ms_now)
        pids=()
        for ((i = 0; i < n; i++)); do
          if [ "$split" = samples ]; then
            if [ "$DRY_RUN" = 1 ]; then frames=(--frames "ceil((F-$i)/$n)"); else frames=(--frames $(((whole_frames - i + n - 1) / n))); fi
          else
            frames=("${converge[@]}")
          fi
          # shellcheck disable=SC2046
          x env CUDA_VISIBLE_DEVICES="$i" "$inr" render "$model" "${common[@]}" "${frames[@]}" $(threads_for "$n") "$option" "$i/$n" \
            -o "$scratch/$tag.b$i.npy" --stats-json "$out/$tag.b$i.stats.json" > "$out/$tag.b$i.log" 2>&1 &
          pids+=($!)
        done
        for p in "${pids[@]}"; do wait "$p" || echo "part process $p failed (log: $out/$tag.b*.log)"; done
        echo "wall $(($(ms_now) - t0)) ms" | tee "$out/$tag.wall"
        for ((i = 0; i < n; i++)); do cp "$scratch/$tag.b$i.brick.json" "$out/" 2> /dev/null; done
        x "$PYTHON" Benchmarks/composite_bricks.py "$scratch/$tag".b*.npy --reference "$scratch/$name.whole.npy" \
          --min-psnr 40 -o "$out/$tag.composite.png" --csv "$out/$tag.csv" | tee "$out/$tag.composite.txt"
        rm -f "$scratch/$tag".b*.npy
      done
    done
    rm -f "$scratch/$name.whole.npy"
  done
  x "$PYTHON" Benchmarks/brick_scaling_summary.py "$out" "$@" | tee "$out/brick_scaling.txt"
  rm -rf "$scratch"
}

suite_run() {
  local models=("$@") size gpus n dirs=() start=$SECONDS split
  [ "${#models[@]}" -gt 0 ] || models=(Testing/Data/real/{coordnet_cylinder_u,ffn_mri_head,siren_cylinder_vorticity}.inr)
  N=${N:-2 4} SPLIT=${SPLIT:-pixels samples} TARGET=${TARGET:-41} MAX_FRAMES=${MAX_FRAMES:-1500}
  for split in ${SPLIT//,/ }; do
    case "$split" in
      pixels | samples | bricks) ;;
      *) echo "scaling: SPLIT must list pixels, samples or bricks, got '$split'" >&2; return 2 ;;
    esac
  done
  if [ "${BACKEND:-cuda}" != cpu ] && [ "$DRY_RUN" = 0 ]; then
    gpus=$(nvidia-smi --list-gpus 2> /dev/null | wc -l)
    for n in ${N//,/ }; do
      [ "$n" -le "$gpus" ] || { echo "scaling: N=$n needs $n GPUs, nvidia-smi lists $gpus" >&2; return 2; }
    done
  fi
  # The compositing needs numpy: the first interpreter with it.
  [ "$DRY_RUN" = 1 ] && PYTHON=${PYTHON:-python3}
  if [ -z "${PYTHON:-}" ]; then
    for py in python3 /usr/bin/python3; do
      if "$py" -c "import numpy" 2> /dev/null; then PYTHON=$py; break; fi
    done
    [ -n "${PYTHON:-}" ] || { echo "scaling: no python3 with numpy (set PYTHON)" >&2; return 2; }
  fi
  local sizes=${SIZES:-1024 2048}
  for size in ${sizes//,/ }; do
    stamp "${size}x${size}"
    BENCH_STEP="${size}x${size}" scaling_at_size "$OUT/$size" "$size" "${models[@]}" > "$OUT/run_$size.log" 2>&1
    grep -E "^== |failed|FAILED" "$OUT/run_$size.log"
    dirs+=("$OUT/$size")
  done
  stamp "table"
  x "$PYTHON" Benchmarks/brick_scaling_summary.py "${dirs[@]}" "${models[@]}" --target 40 \
    --csv "$OUT/scaling.csv" --plot "$OUT/scaling.png" | tee "$OUT/scaling.txt"
  echo "scaling: $((SECONDS - start)) s in all" | tee -a "$OUT/scaling.txt"
}
