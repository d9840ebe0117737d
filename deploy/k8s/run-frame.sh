#!/bin/bash
# Runs frame-job.yaml, waits for every part, then runs merge-job.yaml and waits for it.
#   deploy/k8s/run-frame.sh            (kubectl's current context and namespace)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
timeout=${TIMEOUT:-24h}
kubectl delete job penumbra-frame penumbra-merge --ignore-not-found
kubectl apply -f "$here/frame-job.yaml"
kubectl wait --for=condition=complete --timeout="$timeout" job/penumbra-frame
kubectl apply -f "$here/merge-job.yaml"
kubectl wait --for=condition=complete --timeout="$timeout" job/penumbra-merge
kubectl logs job/penumbra-merge
