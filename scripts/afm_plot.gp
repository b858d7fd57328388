# Error vs frame time of afm for docs/afm.md (run by scripts/afm_docs.sh with
# -e "csv='...'; out='...'; scenes='a b c'"): one curve per (scene, coefs)
# through steps 50, 100, 250, 500; CPU, 2 threads; rel-L2 against reference.
set terminal pngcairo size 820,540 font "DejaVu Sans,11" noenhanced
set output out
set datafile separator ","
set logscale xy
set xlabel "afm frame time, ms (CPU, 2 threads)"
set ylabel "rel-L2 vs reference"
set grid
set key outside right
set title "afm: error vs time (points along a curve: 50, 100, 250, 500 steps)"
coefs = "4 8 16 32"
plot for [s in scenes] for [c in coefs] csv using (strcol(1) eq s && $2 == c+0 ? $4 : NaN):5 \
     with linespoints pt 7 ps 0.7 title sprintf("%s, %s coefs", s, c), \
     0.02 with lines dt 2 lc rgb "#999999" title "2 % target"
