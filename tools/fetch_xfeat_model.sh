#!/usr/bin/env bash
# Gets the XFeat ONNX model this project uses for learned features and checks
# it: XFeat (Potje et al., CVPR 2024, Apache-2.0), as exported by its authors'
# repository verlab/accelerated_features, weights/xfeat.onnx at commit
# c58e74fc86c0e1f9038e0fb8807de59d27dd30d5.
#
#   tools/fetch_xfeat_model.sh                      # download into models/
#   tools/fetch_xfeat_model.sh --from FILE          # copy a file you already have
#   tools/fetch_xfeat_model.sh --dest DIR           # install somewhere else
#
# Then: export AG_XFEAT_MODEL=$PWD/models/xfeat.onnx (or features.model_path
# in the YAML, or --model). Without the model the daemons use SIFT and warn.
set -euo pipefail
cd "$(dirname "$0")/.."
COMMIT=c58e74fc86c0e1f9038e0fb8807de59d27dd30d5
URL="https://raw.githubusercontent.com/verlab/accelerated_features/${COMMIT}/weights/xfeat.onnx"
SHA256=54041f61f0d9b1968451a65fe0fd79e96692b1d8266c54a6939a73e847df5988
from=""
dest="models"
while [ $# -gt 0 ]; do
  case "$1" in
    --from) from="$2"; shift 2 ;;
    --dest) dest="$2"; shift 2 ;;
    -h|--help) sed -n 2,14p "$0"; exit 0 ;;
    *) echo "fetch_xfeat_model: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
mkdir -p "$dest"
tmp="$(mktemp "$dest/.xfeat.onnx.XXXXXX")"
trap 'rm -f "$tmp"' EXIT
if [ -n "$from" ]; then
  [ -f "$from" ] || { echo "fetch_xfeat_model: $from does not exist" >&2; exit 1; }
  cp "$from" "$tmp"
else
  command -v curl >/dev/null || { echo "fetch_xfeat_model: needs curl (apt-get install curl), or use --from FILE" >&2; exit 1; }
  echo "fetch_xfeat_model: downloading $URL"
  curl -fL --retry 3 -o "$tmp" "$URL"
fi
actual="$(sha256sum "$tmp" | cut -d' ' -f1)"
if [ "$actual" != "$SHA256" ]; then
  echo "fetch_xfeat_model: sha256 mismatch: got $actual, expected $SHA256 (not installed)" >&2
  exit 1
fi
mv "$tmp" "$dest/xfeat.onnx"
trap - EXIT
echo "fetch_xfeat_model: installed $dest/xfeat.onnx (sha256 ok)"
echo "  export AG_XFEAT_MODEL=$(cd "$dest" && pwd)/xfeat.onnx"
