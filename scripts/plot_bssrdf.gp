# Plots for docs/bssrdf.md from the CSVs scripts/bench_bssrdf.sh writes.
# Run from the repository root: gnuplot scripts/plot_bssrdf.gp
set datafile separator ","
set terminal pngcairo size 1500,460 font "DejaVu Sans,11"

# ---- diffusion profiles against the random walk ------------------------------------
set output "docs/images/bssrdf/profiles.png"
set multiplot layout 1,3
set logscale y
set format y "10^{%L}"
set xlabel "r (mm)"
set ylabel "R(r) (1/mm^2)"
set key top right
set title "marble, red: dipole vs random walk"
plot "docs/bssrdf/profile_marble.csv" every ::1 using 1:5 with points pt 7 ps 0.5 lc rgb "#999999" title "walk, all light", \
     "" every ::1 using 1:8 with points pt 6 ps 0.6 lc rgb "#cc3311" title "walk, multiple scattering", \
     "" every ::1 using 1:2 with lines lw 2 lc rgb "#0077bb" title "dipole"
set title "skin1, green: dipole vs normalised diffusion"
plot "docs/bssrdf/profile_skin1.csv" every ::1 using 1:6 with points pt 7 ps 0.5 lc rgb "#999999" title "walk, all light", \
     "" every ::1 using 1:9 with points pt 6 ps 0.6 lc rgb "#cc3311" title "walk, multiple scattering", \
     "" every ::1 using 1:3 with lines lw 2 lc rgb "#0077bb" title "dipole", \
     "docs/bssrdf/profile_skin1_burley.csv" every ::1 using 1:3 with lines lw 2 dt 2 lc rgb "#009988" title "normalised diffusion"
set title "marble 4 mm slab, red: multipole R and T"
plot "docs/bssrdf/profile_marble_slab4mm.csv" every ::1 using 1:8 with points pt 6 ps 0.6 lc rgb "#cc3311" title "walk R (multiple)", \
     "" every ::1 using 1:14 with points pt 4 ps 0.6 lc rgb "#ee7733" title "walk T", \
     "" every ::1 using 1:2 with lines lw 2 lc rgb "#0077bb" title "multipole R", \
     "" every ::1 using 1:11 with lines lw 2 dt 2 lc rgb "#33bbee" title "multipole T"
unset multiplot

# ---- frame time and error against splat count -------------------------------------------
set output "docs/images/bssrdf/sweep.png"
set multiplot layout 1,2
set logscale xy
set format y "%g"
set xlabel "splats drawn (valid light samples)"
set key top left
sel(s, p, b) = sprintf("< awk -F, '$1==\"%s\" && $2==\"%s\" && $3==\"%s\"' docs/bssrdf/sweep.csv", s, p, b)
set ylabel "processor time per frame (ms, 512^2; 2-core CPU / llvmpipe)"
set title "frame cost vs splat count"
plot sel("bunny_marble","dipole","cpu") using 5:13 with linespoints lw 2 pt 7 lc rgb "#0077bb" title "bunny dipole cpu", \
     sel("bunny_marble","multipole","cpu") using 5:13 with linespoints lw 2 pt 5 lc rgb "#33bbee" title "bunny multipole cpu", \
     sel("dragon_marble","dipole","cpu") using 5:13 with linespoints lw 2 pt 7 lc rgb "#cc3311" title "dragon dipole cpu", \
     sel("dragon_marble","multipole","cpu") using 5:13 with linespoints lw 2 pt 5 lc rgb "#ee7733" title "dragon multipole cpu", \
     sel("bunny_marble","dipole","gpu") using 5:13 with points pt 6 ps 1.5 lc rgb "#0077bb" title "bunny dipole gpu", \
     sel("bunny_marble","multipole","gpu") using 5:13 with points pt 4 ps 1.5 lc rgb "#33bbee" title "bunny multipole gpu", \
     sel("dragon_marble","dipole","gpu") using 5:13 with points pt 6 ps 1.5 lc rgb "#cc3311" title "dragon dipole gpu", \
     sel("dragon_marble","multipole","gpu") using 5:13 with points pt 4 ps 1.5 lc rgb "#ee7733" title "dragon multipole gpu"
set ylabel "rel-L2 against 65536 requested splats"
set title "sampling error vs splat count (cpu)"
plot sel("bunny_marble","dipole","cpu") using 5:15 with linespoints lw 2 pt 7 lc rgb "#0077bb" title "bunny dipole", \
     sel("bunny_marble","multipole","cpu") using 5:15 with linespoints lw 2 pt 5 lc rgb "#33bbee" title "bunny multipole", \
     sel("dragon_marble","dipole","cpu") using 5:15 with linespoints lw 2 pt 7 lc rgb "#cc3311" title "dragon dipole", \
     sel("dragon_marble","multipole","cpu") using 5:15 with linespoints lw 2 pt 5 lc rgb "#ee7733" title "dragon multipole"
unset multiplot
