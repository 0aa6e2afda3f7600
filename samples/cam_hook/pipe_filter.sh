#!/bin/sh
# A CAM post-processor step that pipes its output through `postproc compensate - -o -`.
#
#   sh samples/cam_hook/pipe_filter.sh OUT.src [MODEL.onnx]
#
# The CAM post writes the program to stdout; postproc reads it on stdin, writes the
# compensated program to stdout, and exits 2 (with `path:line:col: CODE message` on stderr)
# if it cannot compensate. Write to a temporary name and rename only on success, so that a
# failed run never leaves a half-written or uncompensated program where the robot cell
# expects a compensated one. POSTPROC overrides the command (e.g. "python -m postproc").
set -eu
out=${1:?usage: pipe_filter.sh OUT.src [MODEL.onnx]}
model=${2:-}
here=$(dirname "$0")
postproc=${POSTPROC:-postproc}
format=${CAM_FORMAT:-}   # "--csv" for a pose list instead of KRL

tmp="$out.part"
trap 'rm -f "$tmp"' EXIT
# `set -e` sees the status of the last command of a pipe: postproc's, the one that matters
python3 "$here/fake_cam_post.py" --points 100 $format \
  | $postproc compensate - -o - -q ${model:+--model "$model"} --strict > "$tmp"
mv "$tmp" "$out"
