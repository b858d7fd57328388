# Noise vs samples per pixel for docs/pathtrace.md (run by scripts/pathtrace_docs.sh):
# rel-L2 of an N-spp path-traced image against a 2048-spp one, per bundled scene.
set terminal pngcairo size 760,500 font "DejaVu Sans,11" noenhanced
set output "docs/pathtrace/noise_vs_spp.png"
set datafile separator ","
set logscale xy
set xlabel "samples per pixel"
set ylabel "rel-L2 vs 2048 spp"
set xrange [0.8:320]
set yrange [0.01:5]
set grid
set key outside right
set title "pathtrace: noise vs spp (dashed: slope -1/2)"
scenes = "demo homogeneous_sphere cube_torus layered_cube smoke_glow spot_shaft dusty_room smoke_box bunny_fog"
plot for [s in scenes] "docs/pathtrace/noise.csv" using 2:(strcol(1) eq s ? $3 : NaN) with linespoints pt 7 ps 0.7 title s, \
     for [k=-2:1] 10**k / sqrt(x) with lines dt 2 lc rgb "#999999" notitle
