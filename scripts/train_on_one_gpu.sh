#!/bin/bash
# Two models trained from scratch side by side on one GPU in under ten minutes: CONFIG_A through every stage of the
# shipped recipe (vae; prior and decoder at once on the "kicks" windows, joined with merge --take decoder; HHI then
# FWSR beside HSI on the "turns" windows, joined with merge --take hsi), CONFIG_B without the decoder and FWSR
# stages, then evaluated (python -m model_runtime.evaluate). Batches of 512 windows for the VAE and prior; each stage
# stops after its minutes (times SCALE: 1 on a GPU, small for a dry run on the CPU).
#
#   bash scripts/train_on_one_gpu.sh runs/clips_full.npz OUT default paper 1
#
# OUT receives a_full.pt (CONFIG_A, every stage; a_hhi_fwsr.pt and a_hsi.pt before the last join), b_eval.json
# (CONFIG_B's evaluation), bench.jsonl (the default and paper networks' GPU latency) and logs.tgz (every stage's log
# and a timeline). FWSR reads the HHI module only, so it trains after HHI while HSI, whose set-up is the slowest
# (about 2 minutes), still trains. DEV=cpu runs it without a GPU; WORK sets the scratch folder (default
# /tmp/remogen_side_by_side, emptied first); DEADLINE (seconds from the start) bounds CONFIG_B's evaluation.
set -u
LIB=$1; O=$2; CA=$3; CB=$4; S=$5; DEV=${DEV:-auto}; DEADLINE=${DEADLINE:-565}
W=${WORK:-/tmp/remogen_side_by_side}; rm -rf $W; mkdir -p $W/logs $O
T0=$(date +%s)
m() { python3 -c "print(round($1*$S, 3))"; }
stamp() { echo "[$(( $(date +%s) - T0 )) s] $*" | tee -a $W/logs/timeline.txt; }
finish() {
  stamp "finish"
  for d in $W/*/; do n=$(basename $d); for l in $d*.log.jsonl; do [ -f "$l" ] && cp "$l" $W/logs/${n}_$(basename $l); done; done
  [ -f $W/A_final.pt ] && cp $W/A_final.pt $O/a_full.pt
  [ -f $W/A_F/model.pt ] && cp $W/A_F/model.pt $O/a_hhi_fwsr.pt
  [ -f $W/A_S/model.pt ] && cp $W/A_S/model.pt $O/a_hsi.pt
  tar czf $O/logs.tgz -C $W logs
}
trap finish EXIT
run_stage() {  # run_stage NAME STAGE DIR CONFIG MINUTES WORKERS [extra...]
  local name=$1 st=$2 dir=$3 cfg=$4 mins=$5 wk=$6; shift 6
  stamp "start $name"
  python3 -m model_runtime.train $st --library $LIB --out $dir --config $cfg --device $DEV --workers $wk --threads 2 \
     --minutes $(m $mins) --no-progress "$@" > $W/logs/$name.txt 2>&1
  local rc=$?
  stamp "end $name rc=$rc $(grep -a "of .* steps" $W/logs/$name.txt | tail -1)"
}
# The minutes and worker counts below share about nine minutes and 16 CPU cores between the two tracks; HSI gets
# more minutes than HHI because its set-up takes longer and the FWSR stage follows HHI meanwhile.
track() {  # track X CONFIG FULL (1: decoder and FWSR too)
  local X=$1 C=$2 FULL=$3
  run_stage ${X}_vae vae $W/$X $C 1.0 6 --batch 512 --lr 2e-4 --steps 200000
  if [ $FULL = 1 ]; then
    mkdir -p $W/${X}_D && cp $W/$X/*.pt $W/${X}_D/
    run_stage ${X}_prior prior $W/$X $C 1.5 5 --batch 512 --lr 2e-4 --steps 200000 --windows kicks &
    run_stage ${X}_decoder decoder $W/${X}_D $C 1.5 2 --batch 512 --lr 1e-4 --steps 200000 --windows kicks; wait
    mkdir -p $W/${X}_B
    python3 -m model_runtime.training.merge $W/$X/model.pt $W/${X}_D/model.pt --take decoder --out $W/${X}_B/model.pt >> $W/logs/merge.txt 2>&1
  else
    run_stage ${X}_prior prior $W/$X $C 1.5 6 --batch 512 --lr 2e-4 --steps 200000 --windows kicks
    mkdir -p $W/${X}_B && cp $W/$X/model.pt $W/${X}_B/
  fi
  mkdir -p $W/${X}_F $W/${X}_S && cp $W/${X}_B/model.pt $W/${X}_F/ && cp $W/${X}_B/model.pt $W/${X}_S/
  if [ $FULL = 1 ]; then
    ( run_stage ${X}_hhi hhi $W/${X}_F $C 1.2 3 --steps 100000 && run_stage ${X}_fwsr fwsr $W/${X}_F $C 0.7 3 --steps 100000 ) &
    run_stage ${X}_hsi hsi $W/${X}_S $C 2.0 4 --steps 100000 --windows turns; wait
  else
    run_stage ${X}_hhi hhi $W/${X}_F $C 1.2 3 --steps 100000 &
    run_stage ${X}_hsi hsi $W/${X}_S $C 1.3 3 --steps 100000 --windows turns; wait
  fi
  python3 -m model_runtime.training.merge $W/${X}_F/model.pt $W/${X}_S/model.pt --take hsi --out $W/${X}_final.pt >> $W/logs/merge.txt 2>&1
  stamp "merged $X rc=$?"
  if [ $FULL = 0 ]; then
    stamp "start ${X}_eval"
    timeout $(python3 -c "print(int(max(10, $DEADLINE - ($(date +%s) - $T0))))") python3 -m model_runtime.evaluate \
      --model $W/${X}_final.pt --library $LIB --json --plots "" --logs $W/$X --threads 6 > $O/b_eval.json 2> $W/logs/${X}_eval.txt
    stamp "end ${X}_eval rc=$?"
  fi
}
stamp "bench"
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader > $W/logs/gpu.txt 2>&1
python3 -c "import torch; print(torch.__version__, torch.cuda.is_available())" >> $W/logs/gpu.txt 2>&1
if [ "$DEV" != cpu ]; then
  timeout 40 python3 -m model_runtime.bench --device cuda --modes model --configs default,paper --precisions fp32 \
    --frames 100 --json > $O/bench.jsonl 2> $W/logs/bench.txt
fi
stamp "bench done"
track A $CA 1 &
track B $CB 0 &
wait
