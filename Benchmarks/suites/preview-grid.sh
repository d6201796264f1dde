# The reader's preview grid (issue 48 item 3: what ParaView's own filters see of the network):
# preview_grid_benchmark evaluates an r^3 grid over each model's box in the reader's chunks, on the
# GPU where there is one (auto) and on the CPU; median of the repetitions.
SUITE_ABOUT="reader preview grid: r^3 grid evaluation time per backend (preview_grid_benchmark)"
SUITE_COST="a few seconds per model on a GPU; minutes for 256^3 on 2 CPU cores (lower RESOLUTIONS there)"
SUITE_NEEDS="CPU (GPU for the auto rows to use one)"
SUITE_BEFORE=rerun
SUITE_HELP='RESOLUTIONS=64,128,256   grid samples per axis
BACKENDS=auto,cpu        backends (auto, cpu, cuda)
REPS=3                   repetitions (the median is reported)
(-- MODEL.inr ...: the models; default the paper-size models and the shipped hash grid)'
SUITE_TABLES="preview_grid.txt"

suite_build() { bench_build preview_grid_benchmark; }

suite_run() {
  local R=Testing/Data/real models=("$@")
  [ "${#models[@]}" -gt 0 ] || models=($R/siren_cylinder_vorticity.inr $R/ffn_mri_head.inr $R/coordnet_cylinder_u.inr
                                       $R/hashgrid_mri_head_small.inr)
  stamp "preview grids ${RESOLUTIONS:-64,128,256} on ${BACKENDS:-auto,cpu}"
  x "$BUILD/Benchmarks/preview_grid_benchmark" --resolutions "${RESOLUTIONS:-64,128,256}" \
    --backends "${BACKENDS:-auto,cpu}" --reps "${REPS:-3}" --csv "$OUT/preview_grid.csv" "${models[@]}" \
    | tee "$OUT/preview_grid.txt"
  return "${PIPESTATUS[0]}"
}
