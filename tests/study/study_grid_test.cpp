#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "test_util.h"
#include "uplvsm/study/grid_report.h"
#include "uplvsm/study/study_grid.h"

using namespace uplvsm;

TEST(StudyGrid, TableCsvAndPlotFollowTheCells) {
  std::vector<study::GridCell> cells = {
      {"uplvsm", "25 scenes", 25, 20.0, 0.60, std::nan("")},
      {"uplvsm", "100 scenes", 100, 22.0, 0.70, std::nan("")},
      {"lvsm", "25 scenes", 25, 21.0, 0.65, 0.30},
  };
  EXPECT_EQ(study::series_of(cells), (std::vector<std::string>{"uplvsm", "lvsm"}));
  EXPECT_EQ(study::settings_of(cells), (std::vector<std::string>{"25 scenes", "100 scenes"}));
  const auto md = study::grid_markdown(cells, true);
  EXPECT_NE(md.find("| Method | 25 scenes | 100 scenes | Avg. gain |"), std::string::npos) << md;
  EXPECT_NE(md.find("| uplvsm | 20.00 / 0.600 / - | 22.00 / 0.700 / - | 2.00 / 0.100 / - |"), std::string::npos) << md;
  EXPECT_NE(md.find("| lvsm | 21.00 / 0.650 / 0.300 | (not run) | - / - / - |"), std::string::npos) << md;
  const auto csv = study::grid_csv(cells);
  EXPECT_NE(csv.find("lvsm,25 scenes,25,0,21.000000,0.650000,0.300000\n"), std::string::npos) << csv;
  EXPECT_NE(csv.find("uplvsm,25 scenes,25,0,20.000000,0.600000,\n"), std::string::npos) << csv;
  io::PlotOptions po;
  po.log_x = true;
  auto png = study::grid_plot(cells, "psnr", po);
  EXPECT_EQ(png.sizes(), (std::vector<int64_t>{po.height, po.width, 3}));
  EXPECT_THROW(study::grid_plot(cells, "fid", po), std::invalid_argument);
}

// Two seeds of a cell: the table shows their mean and half their PSNR range; a missing LPIPS stays missing.
TEST(StudyGrid, SeedsAreAveragedWithTheirSpread) {
  std::vector<study::GridCell> runs = {
      {"lvsm", "noise sd 0", 0, 20.0, 0.60, 0.30, 777},
      {"lvsm", "noise sd 0.1", 1, 18.0, 0.50, std::nan(""), 777},
      {"lvsm", "noise sd 0", 0, 21.0, 0.70, 0.20, 778},
      {"lvsm", "noise sd 0.1", 1, 18.5, 0.55, std::nan(""), 778},
  };
  const auto cells = study::mean_over_seeds(runs);
  ASSERT_EQ(cells.size(), 2u);
  EXPECT_EQ(cells[0].setting, "noise sd 0");
  EXPECT_DOUBLE_EQ(cells[0].psnr, 20.5);
  EXPECT_DOUBLE_EQ(cells[0].psnr_spread, 0.5);
  EXPECT_DOUBLE_EQ(cells[0].lpips, 0.25);
  EXPECT_EQ(cells[0].runs, 2);
  EXPECT_TRUE(std::isnan(cells[1].lpips));
  const auto md = study::grid_markdown(cells, false);
  EXPECT_NE(md.find("| lvsm | 20.50 ±0.50 / 0.650 / 0.250 | 18.25 ±0.25 / 0.525 / - |"), std::string::npos) << md;
  EXPECT_NE(study::grid_csv(runs).find("lvsm,noise sd 0.1,1,778,18.500000,0.550000,\n"), std::string::npos);
}

// The report a grid leaves: the table over seeds, every run in table.csv, a plot per metric, and held-out curves
// from the runs' periodic evaluations (a run without them adds no curve; no run with them, no curves files).
TEST(StudyGrid, ReportWritesTablePlotsAndHeldOutCurves) {
  const auto dir = test::temp_dir("grid_report");
  std::ofstream(dir / "a.jsonl") << "{\"step\": 10, \"loss\": 0.1, \"mse\": 0.01}\n"
                                 << "{\"step\": 500, \"eval\": {\"psnr\": 21.5}}\n"
                                 << "{\"step\": 1000, \"eval\": {\"psnr\": 22.25}}\n";
  std::vector<study::GridCell> runs = {{"lvsm", "noise sd 0", 0, 22.25, 0.6, std::nan(""), 777},
                                       {"uplvsm", "noise sd 0", 0, 21.0, 0.5, std::nan(""), 777}};
  std::vector<study::RunCurve> curves = {{"lvsm", "noise sd 0", (dir / "a.jsonl").string(), 777},
                                         {"uplvsm", "noise sd 0", (dir / "missing.jsonl").string(), 777}};
  study::GridFigure fig;
  fig.title = "Pose noise", fig.xlabel = "level";
  const auto table = study::write_grid_report(runs, curves, dir.string(), fig, "Two runs.");
  EXPECT_NE(table.find("| lvsm | 22.25 / 0.600 / - |"), std::string::npos) << table;
  for (const auto* file : {"table.md", "table.csv", "stats.csv", "psnr.png", "ssim.png", "curves.csv",
                           "curves_lvsm.png", "levelling.md", "README.md"})
    EXPECT_TRUE(std::filesystem::exists(dir / file)) << file;
  EXPECT_FALSE(std::filesystem::exists(dir / "lpips.png"));
  EXPECT_FALSE(std::filesystem::exists(dir / "scenes.csv"));  // no run kept its per-scene scores
  std::ifstream csv(dir / "curves.csv");
  const std::string text((std::istreambuf_iterator<char>(csv)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text,
            "series,setting,seed,step,psnr\nlvsm,noise sd 0,777,500,21.500000\nlvsm,noise sd 0,777,1000,22.250000\n");
  std::ifstream levelling(dir / "levelling.md");
  const std::string rows((std::istreambuf_iterator<char>(levelling)), std::istreambuf_iterator<char>());
  EXPECT_NE(rows.find("| lvsm noise sd 0 s777 | 1000 | 22.25 | 20.00 | - | too few points |"), std::string::npos)
      << rows;
  const auto empty = test::temp_dir("grid_report_no_curves");
  study::write_grid_report(runs, {curves[1]}, empty.string(), fig, "No curves.");
  EXPECT_FALSE(std::filesystem::exists(empty / "curves.csv"));
  EXPECT_FALSE(std::filesystem::exists(empty / "curves_uplvsm.png"));
}

// The training PSNR is the mean training MSE of the last 1000 steps in dB (not the mean of per-step PSNRs), skipped
// steps and eval lines left out; a run without training lines has none.
TEST(StudyGrid, TrainingPsnrIsTheMeanMseOfTheLastStretch) {
  const auto dir = test::temp_dir("training_psnr");
  std::ofstream(dir / "m.jsonl") << "{\"step\": 10, \"mse\": 1.0}\n"
                                 << "{\"step\": 1500, \"mse\": 0.001}\n"
                                 << "{\"step\": 1500, \"eval\": {\"psnr\": 20.0}}\n"
                                 << "{\"step\": 1600, \"mse\": 0.5, \"skipped\": true}\n"
                                 << "{\"step\": 2000, \"mse\": 0.003}\n";
  const double psnr = study::training_psnr({"lvsm", "125", (dir / "m.jsonl").string(), 777});
  EXPECT_NEAR(psnr, -10 * std::log10(0.002), 1e-9);  // steps 1500 and 2000; step 10 is outside the window
  std::ofstream(dir / "eval_only.jsonl") << "{\"step\": 500, \"eval\": {\"psnr\": 21.5}}\n";
  EXPECT_TRUE(std::isnan(study::training_psnr({"lvsm", "125", (dir / "eval_only.jsonl").string(), 777})));
  EXPECT_TRUE(std::isnan(study::training_psnr({"lvsm", "125", (dir / "missing.jsonl").string(), 777})));
}

// A curve has levelled off when its last 2000 steps rise by less than 0.05 dB per 1000 steps (a least-squares fit,
// so one noisy point does not decide); a falling curve has levelled too; fewer than three points decide nothing.
TEST(StudyGrid, LevellingIsTheSlopeOfTheCurvesLastStretch) {
  io::Series rising{"r", {0, 500, 1000, 1500, 2000, 2500, 3000}, {20, 22, 23, 23.5, 23.7, 23.8, 23.9}};
  auto l = study::levelling(rising);
  EXPECT_EQ(l.points, 5);  // steps 1000..3000
  EXPECT_NEAR(l.slope, 0.42, 1e-9);
  EXPECT_DOUBLE_EQ(l.final_psnr, 23.9);
  EXPECT_FALSE(l.levelled());
  io::Series flat{"f", {4000, 4500, 5000, 5500, 6000}, {25.0, 25.02, 24.98, 25.01, 25.0}};
  EXPECT_TRUE(study::levelling(flat).levelled());
  io::Series falling{"d", {4000, 5000, 6000}, {25.0, 24.8, 24.5}};
  EXPECT_NEAR(study::levelling(falling).slope, -0.25, 1e-9);
  EXPECT_TRUE(study::levelling(falling).levelled());
  io::Series short_curve{"s", {500, 1000}, {20, 21}};
  EXPECT_TRUE(std::isnan(study::levelling(short_curve).slope));
  EXPECT_FALSE(study::levelling(short_curve).levelled());
}

// The gain column is the paper's estimator over every run, each seed its own intercept (a seed that skipped a subset
// still counts), with its interval over the seeds: with two seeds, the two seeds' own gains.
TEST(StudyGrid, GainColumnPoolsTheSeedsWithTheirInterval) {
  std::vector<study::GridCell> runs = {
      {"lvsm", "125", 125, 20.0, 0.6, std::nan(""), 777},   {"lvsm", "500", 500, 20.8, 0.6, std::nan(""), 777},
      {"lvsm", "2000", 2000, 22.0, 0.6, std::nan(""), 777}, {"lvsm", "125", 125, 20.2, 0.6, std::nan(""), 778},
      {"lvsm", "2000", 2000, 23.0, 0.6, std::nan(""), 778}, {"up", "125", 125, 19.0, 0.5, std::nan(""), 777},
      {"up", "500", 500, 19.5, 0.5, std::nan(""), 777},     {"up", "2000", 2000, 19.8, 0.5, std::nan(""), 777},
      {"up", "125", 125, 19.4, 0.5, std::nan(""), 778},     {"up", "500", 500, 19.9, 0.5, std::nan(""), 778},
  };
  const auto md = study::grid_markdown(study::mean_over_seeds(runs), true, runs);
  // lvsm: seed 777's slope over 125 / 500 / 2000 rooms (log4 0, 1, 2) is 1.0, seed 778's over 125 / 2000 is 1.4,
  // pooled (2.0 + 2.8) / (2 + 2) = 1.2; the seeds redrawn give 1.0 to 1.4.
  EXPECT_NE(md.find("| lvsm | 20.10 ±0.10 / 0.600 / - | 20.80 / 0.600 / - | 22.50 ±0.50 / 0.600 / - | "
                    "1.20 [1.00, 1.40] / 0.000 / - |"),
            std::string::npos)
      << md;
  EXPECT_NE(
      // up: seed 777 0.4 (Sxy 0.8 over Sxx 2), seed 778 0.5 over 125 / 500 rooms (0.25 over 0.5): 1.05 / 2.5 = 0.42.
      md.find("| up | 19.20 ±0.20 / 0.500 / - | 19.70 ±0.20 / 0.500 / - | 19.80 / 0.500 / - | "
              "0.42 [0.40, 0.50] / 0.000 / - |"),
      std::string::npos)
      << md;
}

// --report-only passes the runs not done yet as planned cells (runs 0): the table reads "(not run)" until a seed of
// that cell is done, table.csv and the plot leave them out, and the gain needs every setting.
TEST(StudyGrid, PlannedRunsReadNotRunUntilDone) {
  study::GridCell planned{"lvsm", "500", 500, std::nan(""), std::nan(""), std::nan(""), 778};
  planned.runs = 0;
  std::vector<study::GridCell> runs = {
      {"lvsm", "125", 125, 20.0, 0.6, std::nan(""), 777}, planned, {"up", "125", 125, 19.0, 0.5, std::nan(""), 777}};
  auto cells = study::mean_over_seeds(runs);
  auto md = study::grid_markdown(cells, true, runs);
  EXPECT_NE(md.find("| lvsm | 20.00 / 0.600 / - | (not run) | - / - / - |"), std::string::npos) << md;
  EXPECT_NE(md.find("| up | 19.00 / 0.500 / - | (not run) | - / - / - |"), std::string::npos) << md;
  EXPECT_EQ(study::grid_csv(runs).find("lvsm,500"), std::string::npos);
  EXPECT_NO_THROW(study::grid_plot(cells, "psnr", io::PlotOptions{}));
  runs.push_back({"lvsm", "500", 500, 21.0, 0.6, std::nan(""), 777});  // one seed done: the cell is that seed's
  md = study::grid_markdown(study::mean_over_seeds(runs), true, runs);
  EXPECT_NE(md.find("| lvsm | 20.00 / 0.600 / - | 21.00 / 0.600 / - | 1.00 / 0.000 / - |"), std::string::npos) << md;
}

// The pose-noise figure: sigma on a log axis, no noise drawn a decade left of the smallest level (not dropped as
// log(0) would be), with a tick labelled 0.
TEST(StudyGrid, NoNoiseStandsLeftOfTheSmallestLevelOnALogAxis) {
  auto blue = [](const torch::Tensor& img) {
    return ((img.select(2, 0) == 31) & (img.select(2, 1) == 119) & (img.select(2, 2) == 180)).sum().item<int64_t>();
  };
  std::vector<study::GridCell> levels = {{"lvsm", "sd 0.01", 0.01, 26.0, 0.6, std::nan("")},
                                         {"lvsm", "sd 0.1", 0.1, 24.0, 0.5, std::nan("")}};
  io::PlotOptions po;
  po.log_x = true;
  const auto without_zero = blue(study::grid_plot(levels, "psnr", po));
  levels.insert(levels.begin(), {"lvsm", "sd 0", 0.0, 26.5, 0.6, std::nan("")});
  EXPECT_GT(blue(study::grid_plot(levels, "psnr", po)), without_zero + 40);  // its marker and segment
}

// --from-table: a study's own table.csv read back cell for cell (seed included); a seed that is no whole number is
// refused naming the line.
TEST(StudyGrid, TableCellsReadBackWhatGridCsvWrote) {
  const auto dir = test::temp_dir("grid_table");
  const std::vector<study::GridCell> runs = {{"lvsm", "noise sd 0", 0, 29.407487, 0.742866, std::nan(""), 777},
                                             {"up", "noise var 0.1", 0.316, 26.1, 0.64, 0.25, 778}};
  std::ofstream(dir / "table.csv") << study::grid_csv(runs);
  const auto cells = study::read_table_cells((dir / "table.csv").string());
  ASSERT_EQ(cells.size(), 2u);
  EXPECT_EQ(cells[1].series, "up");
  EXPECT_EQ(cells[1].setting, "noise var 0.1");
  EXPECT_EQ(cells[1].seed, 778);
  EXPECT_NEAR(cells[0].psnr, 29.407487, 1e-6);
  EXPECT_TRUE(std::isnan(cells[0].lpips));
  EXPECT_NEAR(cells[1].lpips, 0.25, 1e-6);
  std::ofstream(dir / "seed.csv") << "series,setting,x,seed,psnr,ssim,lpips\nlvsm,a,0,7.5,20,0.5,\n";
  const auto msg = test::error_of([&] { study::read_table_cells((dir / "seed.csv").string()); });
  EXPECT_NE(msg.find("--from-table"), std::string::npos) << msg;
  EXPECT_NE(msg.find("line 2"), std::string::npos) << msg;
  std::ofstream(dir / "reference.csv") << "series,setting,x,psnr,ssim,lpips\n";  // the reference format is not a table
  EXPECT_NE(test::error_of([&] { study::read_table_cells((dir / "reference.csv").string()); }).find("line 1 must be"),
            std::string::npos);
}

// --reference: published numbers as cells; a wrong header or line is refused naming the file and the line.
TEST(StudyGrid, ReferenceCellsAreReadOrRefusedNamingTheLine) {
  const auto dir = test::temp_dir("grid_reference");
  std::ofstream(dir / "ok.csv") << "series,setting,x,psnr,ssim,lpips\nlvsm,2K,2000,24.58,0.814,0.177\nup,8K,8000,23.38,"
                                   "0.773,\n";
  const auto cells = study::read_reference_cells((dir / "ok.csv").string());
  ASSERT_EQ(cells.size(), 2u);
  EXPECT_DOUBLE_EQ(cells[0].x, 2000);
  EXPECT_DOUBLE_EQ(cells[0].lpips, 0.177);
  EXPECT_TRUE(std::isnan(cells[1].lpips));
  std::ofstream(dir / "header.csv") << "series,x,psnr\n";
  EXPECT_NE(test::error_of([&] { study::read_reference_cells((dir / "header.csv").string()); }).find("line 1 must be"),
            std::string::npos);
  std::ofstream(dir / "line.csv")
      << "series,setting,x,psnr,ssim,lpips\nlvsm,2K,2000,24.58,0.814,\nlvsm,8K,8000abc,1,1,\n";
  const auto msg = test::error_of([&] { study::read_reference_cells((dir / "line.csv").string()); });
  EXPECT_NE(msg.find("line.csv line 3"), std::string::npos) << msg;
  EXPECT_NE(test::error_of([&] { study::read_reference_cells((dir / "missing.csv").string()); }).find("cannot open"),
            std::string::npos);
  test::remove_tree(dir);
}

// Legends and axes speak the paper's words; unknown series and metrics pass through as they are.
TEST(StudyGrid, PlotsNameModelsAndMetricsAsThePaperDoes) {
  EXPECT_EQ(study::paper_name("uplvsm"), "UP-LVSM");
  EXPECT_EQ(study::paper_name("ptlvsm"), "PT-LVSM");
  EXPECT_EQ(study::paper_name("lvsm"), "LVSM");
  EXPECT_EQ(study::paper_name("chunk pairs"), "chunk pairs");
  EXPECT_EQ(study::metric_label("psnr"), "PSNR (dB)");
  EXPECT_EQ(study::metric_label("lpips"), "LPIPS");
}
