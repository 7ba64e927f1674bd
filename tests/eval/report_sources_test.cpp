// `uplvsm report`'s sources (eval/report_sources.h): a --model spec read key by key, and a model's directories read
// into what its report shows.
#include <gtest/gtest.h>

#include <fstream>
#include <stdexcept>

#include "test_util.h"
#include "uplvsm/eval/report_sources.h"

using namespace uplvsm;

TEST(ReportSources, AModelSpecIsReadKeyByKey) {
  const auto d = eval::parse_model_spec("label=ours,caption=96 px,run=r,eval=e,video=v1,video=v2");
  EXPECT_EQ(d.label, "ours");
  EXPECT_EQ(d.caption, "96 px");
  EXPECT_EQ(d.run, "r");
  EXPECT_EQ(d.eval, "e");
  EXPECT_EQ(d.videos, (std::vector<std::string>{"v1", "v2"}));
  EXPECT_THROW(eval::parse_model_spec("eval=e"), std::runtime_error);              // no label
  EXPECT_THROW(eval::parse_model_spec("label=a,colour=red"), std::runtime_error);  // unknown key
  EXPECT_THROW(eval::parse_model_spec("label=a,eval"), std::runtime_error);        // no value
}

TEST(ReportSources, ReadsTheEvalsGridsInNameOrderAndEachRendersFirstVideo) {
  const auto dir = test::temp_dir("report_sources");
  std::filesystem::create_directories(dir / "eval" / "scenes");
  for (const auto* name : {"b.png", "a.png", "notes.txt"}) std::ofstream(dir / "eval" / "scenes" / name) << "x";
  std::filesystem::create_directories(dir / "render");
  std::ofstream(dir / "render" / "videos.json")
      << R"([{"trajectory": "orbit", "mp4": "o.mp4", "gif": "o.gif", "width": 96}, {"trajectory": "second"}])";
  eval::ModelDirs d;
  d.label = "ours";
  d.eval = (dir / "eval").string();
  d.videos = {(dir / "render").string()};
  const auto in = eval::report_inputs(d);
  EXPECT_EQ(in.title, "ours");
  EXPECT_EQ(in.metrics_json, (dir / "eval" / "metrics.json").string());
  ASSERT_EQ(in.scene_grids.size(), 2u);
  EXPECT_EQ(in.scene_grids[0], (dir / "eval" / "scenes" / "a.png").string());
  ASSERT_EQ(in.videos.size(), 1u);
  EXPECT_EQ(in.videos[0].label, "orbit");
  EXPECT_EQ(in.videos[0].width, 96);
  EXPECT_TRUE(in.train_log_jsonl.empty());
  d.run = (dir / "no_run").string();
  EXPECT_THROW(eval::report_inputs(d), std::runtime_error);
  d.run.clear();
  d.eval.clear();
  EXPECT_THROW(eval::report_inputs(d), std::runtime_error);
  test::remove_tree(dir);
}
