# The plugin in ParaView on the development machine (CPU backend, under Xvfb; issues 12 and 28):
# what the user waits for. The plugin must be built with ParaView first (the project's default
# build: cmake -S . -B build -G Ninja && cmake --build build); this suite builds nothing. STEPS:
#   drags         interactive_lod.py --orbit-only: camera drags (16 orbit steps of 5 degrees
#                 through InteractiveRender, 1292x765) on the paper-size models
#   time-changes  interactive_lod.py: first visits of a time and time changes (12 scrub steps)
#                 and drags, the coarse slices built ahead
#   fresh-frames  fresh_frames.py: several frames at a lower resolution per time change (F = 1, 4)
#   apply-stall   apply_stall.py: Apply's longest event-loop stall, INR Volume against ParaView's
#                 own Volume and Outline of a 64^3 grid (3 repeats)
# Each writes its CSV (and its printed table as STEP.txt) to OUT. The figures move with the
# machine's load: run it on a quiet machine and note the load.
SUITE_ABOUT="ParaView GUI on the CPU: camera drags, time changes, fresh frames, Apply's stall (pvpython + Xvfb)"
SUITE_COST="about 5-15 min per step on a 2-core machine"
SUITE_NEEDS="CPU + ParaView (pvpython, Xvfb) + the plugin built (default build folder: build)"
SUITE_BEFORE=none
SUITE_DEFAULT_BUILD=build
SUITE_HELP='STEPS=drags       any of: drags time-changes fresh-frames apply-stall
MODELS=...        the models for drags (default the paper-size SIREN and FFN)'

suite_run() {
  local plugin_dir="$BUILD/lib/paraview-plugins/InrVolume" step status=0
  local models=${MODELS:-"Testing/Data/real/siren_cylinder_vorticity.inr Testing/Data/real/ffn_mri_head.inr"}
  if [ "$DRY_RUN" = 0 ]; then
    [ -f "$plugin_dir/InrVolume.so" ] || { echo "paraview-gui: no plugin at $plugin_dir/InrVolume.so (build it first)" >&2; return 2; }
    # shellcheck disable=SC1091
    source Tools/xvfb.sh
    start_xvfb
  fi
  for step in ${STEPS:-drags}; do
    stamp "$step"
    case "$step" in
      drags)
        # shellcheck disable=SC2086
        x pvpython Benchmarks/paraview/interactive_lod.py --plugin "$plugin_dir/InrVolume.so" --models $models \
          --size 1292 765 --orbit-steps 16 --orbit-only --csv "$OUT/drags.csv" > "$OUT/drags.txt" 2>&1 || status=1 ;;
      time-changes)
        x pvpython Benchmarks/paraview/interactive_lod.py --plugin "$plugin_dir/InrVolume.so" \
          --scrub-steps 8 --orbit-steps 12 --converge-seconds 3 --interactive-macrocells-ahead 1 \
          --csv "$OUT/time_changes.csv" > "$OUT/time-changes.txt" 2>&1 || status=1 ;;
      fresh-frames)
        x pvpython Benchmarks/paraview/fresh_frames.py --plugin "$plugin_dir/InrVolume.so" --csv "$OUT/fresh_frames.csv" \
          > "$OUT/fresh-frames.txt" 2>&1 || status=1 ;;
      apply-stall)
        x pvpython Benchmarks/paraview/apply_stall.py --plugin-dir "$plugin_dir" --repeat 3 --csv "$OUT/apply_stall.csv" \
          > "$OUT/apply-stall.txt" 2>&1 || status=1 ;;
      *) echo "paraview-gui: unknown step $step (drags time-changes fresh-frames apply-stall)" >&2; status=2 ;;
    esac
    tail -15 "$OUT/$step.txt" 2> /dev/null
  done
  [ "$DRY_RUN" = 1 ] || stop_xvfb
  return $status
}
