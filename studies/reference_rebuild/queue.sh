#!/usr/bin/env bash
# The rest of quick's rebuild (issue 54), in the order it pays off, as one background job on a
# 2-core machine; every step resumes from the store, so starting it again after an interruption
# redoes nothing that finished. Folding (moving a finished encoder into the repo) stays a manual
# step: `python studies/reference_rebuild/rebuild.py fold --store S --task T --encoder E`, then
# test_shipped_latents and a commit per encoder (see README.md).
#
#   nohup bash studies/reference_rebuild/queue.sh /work/store > /work/logs/queue.log 2>&1 &
set -euo pipefail
STORE=${1:?usage: queue.sh STORE}
cd "$(dirname "$0")/../.."
export OMP_NUM_THREADS=1 MKL_NUM_THREADS=1
ORIGINAL=(vae vae_lowkl success success_lowkl pred_z pred_z_lowkl pred_im pred_im_lowkl smooth
          smooth_lowkl vae_lowkl_d4 vae_lowkl_d64 vae_lowkl_image vae_lowkl_ft_proprio
          time_contrastive curl supervised supervised_task oracle_task oracle random pca
          proprio_only)

not_shipped() {  # the original encoders of task $1 whose latents quick does not ship yet
    python - "$1" "${ORIGINAL[@]}" <<'PY'
import json, sys
task, names = sys.argv[1], sys.argv[2:]
sets = json.load(open("leaderboards/quick/latents/manifest.json"))["sets"]
shipped = {s["encoder"] for s in sets if s["task"] == task}
print(" ".join(f"--encoder {n}" for n in names if n not in shipped))
PY
}

lanes() {  # two one-worker lanes over the original encoders of task $1 not shipped yet
    local enc
    enc=$(not_shipped "$1")
    [ -z "$enc" ] && return 0
    # shellcheck disable=SC2086
    python studies/reference_rebuild/rebuild.py run --store "$STORE" --task "$1" --lane 0 \
        --lanes 2 --workers 1 $enc &
    # shellcheck disable=SC2086
    python studies/reference_rebuild/rebuild.py run --store "$STORE" --task "$1" --lane 1 \
        --lanes 2 --workers 1 $enc
    wait
}

# 1. PegInHole-v0: the original encoders not rebuilt yet (finished ones are reused at once)
lanes PegInHole-v0
# 2. Door-v0, the zoo: regenerates the task's data, then trains the 11 zoo encoders without RL;
#    when they reproduce bit for bit (as on PegInHole-v0), their committed SAC seeds stand
repbench run --suite leaderboards/quick/zoo/suite.toml --task Door-v0 --no-rl --store "$STORE" \
    --workers 2 --out /tmp/zoo_door
# 3. Door-v0, the original encoders: trained on the regenerated data, 3 SAC seeds each
lanes Door-v0
