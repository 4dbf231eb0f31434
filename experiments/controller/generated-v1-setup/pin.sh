#!/bin/sh
# Pin a training run's checkpoints as they come (train-foam keeps only its last two): every 20 s, each
# checkpoint whose update is a multiple of EVERY (default 10) and not pinned yet is copied with the run's
# config.json into PIN/u<update>/, a run directory that jaxsimrl.load_policy and `jaxsimrl solve --policy`
# read. Runs until killed.
#   sh experiments/controller/generated-v1-setup/pin.sh RUN PIN [EVERY]
RUN=$1
PIN=$2
EVERY=${3:-10}
mkdir -p "$PIN"
while :; do
    for ckpt in "$RUN"/checkpoints/[0-9]*; do
        [ -d "$ckpt" ] || continue
        update=$(basename "$ckpt")
        case $update in *[!0-9]*) continue ;; esac  # orbax's N.orbax-checkpoint-tmp while it writes
        dest="$PIN/u$update"
        [ $((update % EVERY)) -eq 0 ] || continue
        [ -d "$dest" ] && continue
        mkdir -p "$dest.partial/checkpoints" && cp "$RUN/config.json" "$dest.partial/" &&
            cp -r "$ckpt" "$dest.partial/checkpoints/" && mv "$dest.partial" "$dest"
    done
    sleep 20
done
