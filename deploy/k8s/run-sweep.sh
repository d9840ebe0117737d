#!/bin/bash
# Plans the sweep in a one-off pod, runs its items (completions = the number of items), then
# collects them:
#   deploy/k8s/run-sweep.sh
# The sweep's arguments are those of sweep-items-job.yaml (SWEEP_ARGS); the pod needs the
# same volume, so the plan runs as a Job too.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
timeout=${TIMEOUT:-24h}
kubectl delete job penumbra-sweep-plan penumbra-sweep-items penumbra-sweep-collect --ignore-not-found
# The plan Job: the collect manifest with --plan for --collect.
sed -e 's/penumbra-sweep-collect/penumbra-sweep-plan/' -e 's/--collect/--plan/' "$here/sweep-collect-job.yaml" |
    kubectl apply -f -
kubectl wait --for=condition=complete --timeout="$timeout" job/penumbra-sweep-plan
n=$(kubectl logs job/penumbra-sweep-plan | tail -n 1)
case "$n" in '' | *[!0-9]*) echo "the plan printed no item count: $n" >&2; exit 1 ;; esac
sed -e "s/^  completions: .*/  completions: $n/" "$here/sweep-items-job.yaml" | kubectl apply -f -
kubectl wait --for=condition=complete --timeout="$timeout" job/penumbra-sweep-items
kubectl apply -f "$here/sweep-collect-job.yaml"
kubectl wait --for=condition=complete --timeout="$timeout" job/penumbra-sweep-collect
kubectl logs job/penumbra-sweep-collect
